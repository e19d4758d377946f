#pragma once
// The saw profile's meaning, without any transport: PDOs bound to a process image, the image
// rendered as a typed DDS sample, and set values validated and written into the image. The saw
// gateway wires it to a bus loop and DDS; the unit tests drive it with frames built from the spec.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "canopen/process_image.hpp"
#include "gateways/codecs/named_bits.hpp"
#include "gateways/codecs/other_values.hpp"
#include "msgs/saw.h"
#include "profiles/line_config.hpp"

namespace lb::gateways {

class SawCodec {
 public:
  struct Pdo {
    const profiles::DevicePdo* def;
    canopen::PdoBinding binding;
  };
  struct RawSetpoint {
    bool program_on = false;
    bool wall_thickening = false;
    bool corrugated = false;
    std::uint64_t sync_speed = 0;      // 6005h, 0.01 %
    std::uint64_t product_length = 0;  // 6002h, 0.1 mm
  };

  // Throws std::runtime_error (start-up) when the profile lacks an object or bit a saw needs.
  // pdos: the device's PDOs (profile defaults with overrides). rpdos_received: a monitor bus, where
  // the line controller's RPDOs are decoded too (other_values.hpp).
  SawCodec(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos, bool rpdos_received = false);
  SawCodec(const SawCodec&) = delete;
  SawCodec& operator=(const SawCodec&) = delete;

  const std::vector<Pdo>& pdos() const { return pdos_; }
  // The PDO as the device has it (its boot found it): refused, and nothing changed, when the
  // bridge could not decode or send by it.
  Result<void> use_pdo(std::size_t pdo, const profiles::DevicePdo& actual);
  // Writes a received PDO (TPDO, or an RPDO seen on a monitor bus) into the image.
  Result<void> receive(std::size_t pdo, std::span<const std::uint8_t> payload) {
    return pdos_[pdo].binding.unpack_into(payload, image_);
  }
  std::uint8_t pack(std::size_t pdo, std::span<std::uint8_t, 8> out) const {
    return pdos_[pdo].binding.pack_from(image_, out);
  }

  // Everything the image holds, in engineering units (stamp, NMT state, online are the caller's).
  void fill(linebridge_msgs::msg::SawStatus& status) const;
  bool cutting() const;

  // Range and capability checks of a set value; any thread (reads only the profile).
  Result<RawSetpoint> validate(const linebridge_msgs::msg::SawSetpoint& sp) const;
  // Into the RPDO image; toggles "change of length" whenever the product length changes, which
  // makes the saw take the new length after its next cut.
  void apply(const RawSetpoint& raw);
  // A single control-word bit (momentary commands).
  void set_control_bit(unsigned bit, bool on);
  const profiles::BitSet& control_word() const { return bitset("control_word"); }

 private:
  struct Object {
    const profiles::ObjectDef* def = nullptr;
    std::size_t slot = canopen::ProcessImage::npos;
  };
  Object bind(std::string_view name);
  const profiles::BitSet& bitset(std::string_view name) const;

  const profiles::Profile& profile_;
  canopen::ProcessImage image_;
  Object status_word_, control_word_, counter_value_, saw_counter_, product_speed_, sync_speed_set_, length_set_;
  NamedBits<linebridge_msgs::msg::SawStatusWord> status_bits_;
  NamedBits<linebridge_msgs::msg::SawControlWord> control_bits_;
  unsigned bit_program_on_ = 0, bit_change_of_length_ = 0, bit_saw_cutting_ = 0;
  std::optional<unsigned> bit_count_mode_;  // from saw 3.1 on
  std::optional<unsigned> bit_wall_thickening_;
  std::optional<OtherValues> others_;      // after the typed objects are bound
  std::vector<profiles::DevicePdo> defs_;  // what each PDO is decoded and sent by; never resized
  std::vector<Pdo> pdos_;
};

}  // namespace lb::gateways
