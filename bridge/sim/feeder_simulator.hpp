#pragma once
// The dynamics of a CiA 414-2 feeder control box with a few feeders (sub 0 of the per-feeder
// arrays says how many): feeder status that follows feeder commands (600Eh), feeder functions
// that refuse changes of what is not available (6001h), supported trigger sources (6005h), the
// loom controller's RPDOs (event-driven, applied at once), and TPDO1 unwinding-time events while
// the loom runs (600Ah start advice or slow motion). Its CANopen side is SimulatedNode's.
//
// Fault injection (manufacturer-specific 2001h, UNSIGNED16, rw, written by SDO): low byte = feeder
// (1..count), high byte = the 6007h condition to raise (e.g. 0x0402: feeder 2, yarn broken). The
// feeder goes to error mode, 6007h sub n takes the condition and an EMCY FF10h carries the new
// bitmap. A condition of 0 clears that feeder, feeder 0 clears all; a feeder command "reset"
// (600Eh = 04h) clears that feeder too. Every clearing sends FF10h with the remaining bitmap and,
// once it is empty, an EMCY 0000h (error reset) with the error register that remains. FF10h is
// one active error of the box while any feeder is in error (each of these EMCYs also goes into
// its 1003h error history). Conditions the table does not define are raised as given, so a
// bridge's handling of undefined codes can be tested.

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "profiles/line_config.hpp"
#include "sim/device_simulator.hpp"
#include "sim/simulated_node.hpp"

namespace lb::sim {

class FeederSimulator : public DeviceSimulator {
 public:
  static constexpr unsigned kFeeders = 4;
  static constexpr std::uint16_t kFaultInjection = 0x2001;

  FeederSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile);
  void start() override;

 private:
  const profiles::ObjectDef& object(std::string_view name) const;
  const profiles::BitSet& bitset(std::string_view name) const;
  void reset();
  void add_objects();  // 2001h and the checks of SDO writes to feeder commands, functions, trigger sources
  std::optional<std::uint32_t> on_fault_injection(std::uint64_t value);
  std::optional<std::uint32_t> on_command(unsigned feeder, std::uint64_t command);
  std::optional<std::uint32_t> on_functions(unsigned feeder, std::uint64_t word);
  void raise(unsigned feeder, std::uint64_t condition);
  void clear(unsigned feeder);
  void on_rpdo(std::span<const canopen::PdoEntry> mapped);
  void unwind();

  canopen::BusLoop& loop_;
  const profiles::DeviceConfig& device_;
  const profiles::Profile& profile_;
  SimulatedNode node_;
  std::size_t loom_status_, unwinding_time_;
  canopen::BusLoop::TimerId unwind_timer_{};

  bool loom_running_ = false;
  std::uint32_t bitmap_ = 0;  // feeders in error, bit k = feeder k+1
  unsigned next_feeder_ = 0;
  unsigned winding_ = 0;
};

}  // namespace lb::sim
