#pragma once
// The columns of the safety table (test_safety_*.cpp): every registered device type as the bus
// shows it, written by hand from its profile YAML (config/profiles/) and its specification
// (/work/shared/specs), never from the bridge's or the simulator's tables:
//   - the RPDOs the bridge sends that carry an enabling level, and what "on" looks like in them;
//   - the profile's stopping command an operator presses, and the frame that shows it;
//   - how an operator sets the enabling level over DDS (which set-value type);
//   - a PDO parameter a restarted bridge's line file may change on the running device.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "can/can_frame.hpp"

namespace lb::test::safety {

using FrameMatch = std::function<bool(const lb::can::CanFrame&)>;

// A frame that shows an operator's request on the bus.
struct FrameProof {
  std::string what;  // e.g. "RPDO1 (205h) with 6020h bit 5 stop_immediately"
  FrameMatch match;
};

// An RPDO the bridge sends that carries an enabling level.
struct EnablingRpdo {
  std::uint32_t cob_id;
  std::string what;    // e.g. "RPDO1 205h: 6020h bits 0 saw_program_on, 1 wall_thickening"
  FrameMatch enabled;  // the frame has an enabling bit or field non-zero
};

// Which set-value type an operator writes (idl/*.idl): its topic and answer topic follow.
enum class SetValues { saw, puller, corrugator, winder, loom };

struct SafetyDevice {
  std::string column;  // the test's parameter name: saw31, saw10, puller, corrugator, feeder, winder
  std::string name;    // the device's name in the line file
  int node;
  std::string profile;
  std::string version;
  SetValues set_values;
  std::vector<EnablingRpdo> enabling;
  // Pressed by the operator: the profile's `stopping` command (line-wide `command` service), or for
  // the feeder box the feeder_command stop_mode (600Eh); and the frame that shows it.
  std::string stopping_command;
  FrameProof stop_frame;
  // What the enabling-off set value must make the bus show (every enabling RPDO with its level off).
  std::vector<FrameProof> off_frames;
  // The line file's `pdos:` override (under the device, indented by four) that a running device does
  // not hold, and the SDO download (index, sub) of the bridge that writes it.
  std::string pdo_change;
  std::uint16_t pdo_change_index;
  std::uint8_t pdo_change_sub;

  std::uint32_t rpdo(int n) const { return 0x100u + 0x100u * static_cast<std::uint32_t>(n) + node; }
  std::uint32_t heartbeat_id() const { return 0x700u + static_cast<std::uint32_t>(node); }
  std::uint32_t sdo_request_id() const { return 0x600u + static_cast<std::uint32_t>(node); }
  bool enabled(const lb::can::CanFrame& f) const {
    for (const auto& e : enabling) {
      if (f.id == e.cob_id && e.enabled(f)) return true;
    }
    return false;
  }
  const EnablingRpdo* enabling_rpdo(std::uint32_t id) const {
    for (const auto& e : enabling) {
      if (e.cob_id == id) return &e;
    }
    return nullptr;
  }
  // A frame the device itself sends (CiA 301 predefined connection set): its heartbeat or boot-up
  // (700h), EMCY (080h), SDO answers (580h) and TPDOs 1-4 (180h, 280h, 380h, 480h). A spoofed one
  // of those is never among the recorded frames (the spy does not hear what it sends).
  bool own(const lb::can::CanFrame& f) const {
    const auto n = static_cast<std::uint32_t>(node);
    return f.id == 0x700 + n || f.id == 0x080 + n || f.id == 0x580 + n || f.id == 0x180 + n || f.id == 0x280 + n ||
           f.id == 0x380 + n || f.id == 0x480 + n;
  }
};

namespace detail {

inline std::string fmt_rpdo1(std::uint32_t id, const std::string& what) {
  return fmt::format("RPDO1 {:03X}h: {}", id, what);
}

inline bool on_cob(const lb::can::CanFrame& f, std::uint32_t id, std::uint8_t min_len) {
  return f.id == id && !f.rtr && f.len >= min_len;
}

// CiA 420 RPDO1 (6020h control word first, little-endian): a bit of its low byte set or clear.
inline FrameProof control_bit(std::uint32_t id, std::uint8_t mask, bool set, std::string what) {
  return {std::move(what),
          [id, mask, set](const lb::can::CanFrame& f) { return on_cob(f, id, 2) && ((f.data[0] & mask) != 0) == set; }};
}

// The saw's columns differ only in version and node: CiA 420-4 1.0 (spec 004, bit layout) and 3.1
// (spec 002): RPDO1 200h + node = 6020h control word (16), 6005h sync speed (16), 6002h product
// length (32). 6020h bit 0 s "saw program on/off" and bit 1 wall thickening are the profile's
// `enabling`; bit 5 si "stop immediately" is `stopping`. TPDO2 (1801h) transmission type is rw.
inline SafetyDevice saw(std::string column, int node, std::string version) {
  const auto n = static_cast<std::uint32_t>(node);
  const std::uint32_t rpdo1 = 0x200 + n;
  SafetyDevice d{std::move(column),
                 "saw1",
                 node,
                 "cia420-4",
                 std::move(version),
                 SetValues::saw,
                 {{rpdo1, fmt_rpdo1(rpdo1, "6020h bits 0 saw_program_on, 1 wall_thickening"),
                   [rpdo1](const lb::can::CanFrame& f) { return on_cob(f, rpdo1, 2) && (f.data[0] & 0x03) != 0; }}},
                 "stop_immediately",
                 control_bit(rpdo1, 0x20, true, fmt_rpdo1(rpdo1, "6020h bit 5 stop_immediately set")),
                 {control_bit(rpdo1, 0x03, false, fmt_rpdo1(rpdo1, "6020h bits 0 and 1 clear (program off)"))},
                 "    pdos: {tpdo2: {transmission_type: 2}}\n",
                 0x1801,
                 2};
  return d;
}

// A CiA 420 drive shape (puller 420-2 1.0 spec 001, corrugator 420-3 3.1 spec 003, the example
// winder): RPDO1 200h + node = 6020h control word (16), 6002h speed set value (16). 6020h bit 6
// extruder running is `enabling`; bit 0 (motor stop, drive stop, winder stop: "start prevention")
// is `stopping`. TPDO2 (1801h) transmission type is rw.
inline SafetyDevice drive(std::string column, std::string name, int node, std::string profile, std::string version,
                          SetValues set_values, std::string stop, const std::string& stop_bit_name) {
  const auto n = static_cast<std::uint32_t>(node);
  const std::uint32_t rpdo1 = 0x200 + n;
  SafetyDevice d{std::move(column),
                 std::move(name),
                 node,
                 std::move(profile),
                 std::move(version),
                 set_values,
                 {{rpdo1, fmt_rpdo1(rpdo1, "6020h bit 6 extruder_running"),
                   [rpdo1](const lb::can::CanFrame& f) { return on_cob(f, rpdo1, 2) && (f.data[0] & 0x40) != 0; }}},
                 std::move(stop),
                 control_bit(rpdo1, 0x01, true, fmt_rpdo1(rpdo1, "6020h bit 0 " + stop_bit_name + " set")),
                 {control_bit(rpdo1, 0x40, false, fmt_rpdo1(rpdo1, "6020h bit 6 clear (extruder stopped)"))},
                 "    pdos: {tpdo2: {transmission_type: 2}}\n",
                 0x1801,
                 2};
  return d;
}

}  // namespace detail

// CiA 420-4 3.1 saw at node 5.
inline const SafetyDevice& saw31() {
  static const SafetyDevice d = detail::saw("saw31", 5, "3.1");
  return d;
}
// CiA 420-4 1.0 saw at node 6.
inline const SafetyDevice& saw10() {
  static const SafetyDevice d = detail::saw("saw10", 6, "1.0");
  return d;
}
// CiA 420-2 1.0 puller at node 3: 6020h bit 0 m "motor stop (start prevention)".
inline const SafetyDevice& puller() {
  static const SafetyDevice d = detail::drive("puller", "puller1", 3, "cia420-2", "1.0", SetValues::puller,
                                              "motor_stop", "motor_stop");
  return d;
}
// CiA 420-3 3.1 corrugator at node 7: 6020h bit 0 d "stop drive (start prevention)".
inline const SafetyDevice& corrugator() {
  static const SafetyDevice d = detail::drive("corrugator", "corr1", 7, "cia420-3", "3.1", SetValues::corrugator,
                                              "drive_stop", "drive_stop");
  return d;
}
// The example winder (lb-example-winder 1.0, test-only) at node 9: 6020h bit 0 winder_stop.
inline const SafetyDevice& winder() {
  static const SafetyDevice d = detail::drive("winder", "winder1", 9, "lb-example-winder", "1.0", SetValues::winder,
                                              "winder_stop", "winder_stop");
  return d;
}

// CiA 414-2 1.1 feeder box at node 10, the bridge as loom controller (spec 000, 4.3-4.4, 5.2.11,
// 5.2.14): RPDO2 300h + node = 600Ah loom status (8), 6004h weft filling (32): any loom status but
// 0 (stop) lets the feeders run; RPDO3 400h + node = 600Dh digital outputs sub 1..8 (8 each): any
// output on switches an actuator. Both are the profile's `enabling`. The stop an operator presses
// is feeder_command stop_mode: 600Eh sub feeder = 03h, an SDO download to 600h + node. TPDO1
// (1800h) transmission type is rw.
inline const SafetyDevice& feeder() {
  static const SafetyDevice d = [] {
    constexpr std::uint32_t rpdo2 = 0x30A, rpdo3 = 0x40A, sdo = 0x60A;
    const auto outputs_on = [](const lb::can::CanFrame& f) {
      for (unsigned i = 0; i < f.len; ++i) {
        if (f.data[i] != 0) return true;
      }
      return false;
    };
    return SafetyDevice{
        "feeder",
        "feeders",
        10,
        "cia414-2",
        "1.1",
        SetValues::loom,
        {{rpdo2, "RPDO2 30Ah: 600Ah loom_status != 0",
          [](const lb::can::CanFrame& f) { return detail::on_cob(f, rpdo2, 1) && f.data[0] != 0; }},
         {rpdo3, "RPDO3 40Ah: 600Dh digital_outputs != 0",
          [outputs_on](const lb::can::CanFrame& f) { return detail::on_cob(f, rpdo3, 1) && outputs_on(f); }}},
        "stop_mode",
        {"SDO download 60Ah: 600Eh sub 1 = 03h (stop_mode)",
         [](const lb::can::CanFrame& f) {
           return detail::on_cob(f, sdo, 5) && (f.data[0] & 0xE0) == 0x20 && f.data[1] == 0x0E && f.data[2] == 0x60 &&
                  f.data[3] == 1 && f.data[4] == 0x03;
         }},
        {{"RPDO2 30Ah with 600Ah = 0 (stop)",
          [](const lb::can::CanFrame& f) { return detail::on_cob(f, rpdo2, 1) && f.data[0] == 0; }},
         {"RPDO3 40Ah with every 600Dh output off",
          [outputs_on](const lb::can::CanFrame& f) { return detail::on_cob(f, rpdo3, 1) && !outputs_on(f); }}},
        "    pdos: {tpdo1: {transmission_type: 254}}\n",
        0x1800,
        2};
  }();
  return d;
}

// Every device type, each named by its column (the two saws share a name in the safety table's rows):
// the line of the redundancy tests (test_hot_standby.cpp, test_flying_master.cpp).
inline const std::vector<const SafetyDevice*>& every_device_type() {
  static const std::vector<SafetyDevice> named = [] {
    std::vector<SafetyDevice> d{saw31(), saw10(), puller(), corrugator(), winder(), feeder()};
    for (auto& x : d) x.name = x.column;
    return d;
  }();
  static const std::vector<const SafetyDevice*> d = [] {
    std::vector<const SafetyDevice*> out;
    for (const auto& x : named) out.push_back(&x);
    return out;
  }();
  return d;
}

// A frame's data in hex, as candump writes it ("07008813E02E0000").
inline std::string payload(const lb::can::CanFrame& f) {
  std::string s;
  for (unsigned i = 0; i < f.len; ++i) s += fmt::format("{:02X}", f.data[i]);
  return s;
}

}  // namespace lb::test::safety
