#pragma once
// What the CiA 420 puller (part 2) and corrugator (part 3) have in common, without any transport
// or message type: the same PDOs (TPDO1 status word, speed actual, load actual and an optional
// manufacturer-specific word; TPDO2 set echo and product speed; RPDO1 control word and speed set
// value), objects named "<device>_speed_..." by the profile, and the set echo check. DriveCodec
// renders it as the device's DDS types.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "base/result.hpp"
#include "canopen/process_image.hpp"
#include "gateways/codecs/other_values.hpp"
#include "gateways/codecs/set_echo_monitor.hpp"
#include "profiles/line_config.hpp"

namespace lb::gateways {

class DriveImage {
 public:
  struct Pdo {
    const profiles::DevicePdo* def;
    canopen::PdoBinding binding;
    std::optional<profiles::PdoTail> manufacturer_data;  // TPDOs only: the optional trailing word
    bool carries_echo = false;                           // maps the set echo: one echo sample
  };
  struct RawSetpoint {
    bool extruder_running = false;
    std::uint64_t speed_set = 0;  // 6002h, 0.01 %, two's complement in the low 16 bits
  };

  // device: the type's name (puller, corrugator, ...), the prefix of its speed and load object names.
  // Throws std::runtime_error (start-up) when the profile lacks an object or bit this needs.
  // pdos: the device's PDOs (profile defaults with overrides); they must outlive the image.
  // rpdos_received: a monitor bus, where the line controller's RPDOs are decoded too.
  DriveImage(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos, std::string_view device,
             SetEchoMonitor::Settings echo = {}, bool rpdos_received = false);

  DriveImage(const DriveImage&) = delete;
  DriveImage& operator=(const DriveImage&) = delete;

  const std::vector<Pdo>& pdos() const { return pdos_; }
  // The PDO as the device has it (its boot found it): refused, and nothing changed, when the
  // bridge could not decode or send by it.
  Result<void> use_pdo(std::size_t pdo, const profiles::DevicePdo& actual);
  // A received PDO (TPDO, or an RPDO seen on a monitor bus) into the image; refused untouched when
  // shorter than its mapping.
  Result<void> receive(std::size_t pdo, std::span<const std::uint8_t> payload);
  std::uint8_t pack(std::size_t pdo, std::span<std::uint8_t, 8> out) const {
    return pdos_[pdo].binding.pack_from(image_, out);
  }

  // Range check of a set value; any thread (reads only the profile).
  Result<RawSetpoint> validate(bool extruder_running, double speed_set_percent) const;
  void apply(const RawSetpoint& raw);  // into the RPDO image; momentary bits stay as they are
  void set_control_bit(unsigned bit, bool on);

  const profiles::BitSet& bitset(std::string_view name) const;
  const profiles::Profile& profile() const { return profile_; }

  std::uint64_t status_word() const { return image_.get(status_word_.slot); }
  std::uint64_t control_word() const { return image_.get(control_word_.slot); }
  bool extruder_running() const { return (control_word() >> bit_extruder_running_) & 1U; }
  double speed_actual_percent() const { return engineering(speed_actual_); }
  double load_actual_percent() const { return engineering(load_actual_); }
  double speed_set_echo_percent() const { return engineering(speed_echo_); }
  double product_speed_m_per_min() const { return engineering(product_speed_); }
  double speed_set_percent() const { return engineering(speed_set_); }
  // From the last TPDO that could carry it: nullopt when that frame was too short for it.
  std::optional<std::uint16_t> manufacturer_status_word() const { return manufacturer_status_word_; }
  bool set_echo_mismatch() const { return echo_.mismatch(); }
  void fill_other_values(std::vector<linebridge_msgs::msg::ProcessValue>& out) const { others_->fill(image_, out); }

 private:
  struct Object {
    const profiles::ObjectDef* def = nullptr;
    std::size_t slot = canopen::ProcessImage::npos;
  };
  Object bind(const std::string& name);
  double engineering(const Object& o) const { return o.def->to_engineering(image_.get(o.slot)); }
  std::int64_t signed_raw(const Object& o) const;

  const profiles::Profile& profile_;
  canopen::ProcessImage image_;
  Object status_word_, control_word_, speed_actual_, load_actual_, speed_echo_, product_speed_, speed_set_;
  unsigned bit_extruder_running_ = 0;
  std::vector<profiles::DevicePdo> defs_;  // what each PDO is decoded and sent by; never resized
  std::vector<Pdo> pdos_;
  std::optional<std::uint16_t> manufacturer_status_word_;
  SetEchoMonitor echo_;
  std::optional<OtherValues> others_;  // after the typed objects are bound
};

}  // namespace lb::gateways
