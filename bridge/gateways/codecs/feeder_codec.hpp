#pragma once
// The feeder profile's meaning (CiA 414-2), without any transport: TPDO1 and the loom
// controller's RPDOs bound to a process image, codes decoded by the profile's value tables and
// bit sets, the EMCY FF10h bitmap, and every configuration write and loom set value validated
// against the profile's access, ranges and tables before it can reach CAN. The feeder gateway wires
// it to a bus loop, SDO and DDS; the unit tests drive it with words written from the spec.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "canopen/process_image.hpp"
#include "gateways/codecs/other_values.hpp"
#include "msgs/feeder.h"
#include "profiles/line_config.hpp"

namespace lb::gateways {

class FeederCodec {
 public:
  static constexpr unsigned kMaxFeeders = 254;    // sub-indices 01h..FEh
  static constexpr unsigned kBitmapFeeders = 32;  // EMCY FF10h carries feeders 1..32

  struct Pdo {
    const profiles::DevicePdo* def;
    canopen::PdoBinding binding;
  };
  // One SDO write that passed every check: exactly what goes on CAN.
  struct Write {
    const profiles::ObjectDef* object;
    std::uint64_t raw;
  };
  // A loom set value in raw units; a part left out is not sent.
  struct RawLoom {
    std::optional<std::uint64_t> loom_status;
    std::uint64_t weft_filling = 0;  // with loom_status (RPDO2 carries both)
    std::optional<std::uint64_t> trigger;
    std::optional<std::array<std::uint64_t, 5>> picks;
    std::vector<std::uint64_t> outputs;  // 600Dh groups 1..n (RPDO3); empty: not sent
  };
  static constexpr unsigned kOutputGroups = 8;  // 600Dh sub 1..8

  // Throws std::runtime_error (start-up) when the profile lacks an object or bit set a feeder
  // needs. pdos: the device's PDOs; they must outlive the codec.
  // rpdos_received: a monitor bus, where the loom controller's RPDOs are decoded (other_values.hpp).
  FeederCodec(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos, bool rpdos_received = false);

  const profiles::Profile& profile() const { return profile_; }
  FeederCodec(const FeederCodec&) = delete;
  FeederCodec& operator=(const FeederCodec&) = delete;

  const std::vector<Pdo>& pdos() const { return pdos_; }
  // The PDO as the device has it (its boot found it): refused, and nothing changed, when the
  // bridge could not decode or send by it.
  Result<void> use_pdo(std::size_t pdo, const profiles::DevicePdo& actual);
  // A received PDO (TPDO1, or a loom controller's RPDO on a monitor bus) into the image.
  Result<void> receive(std::size_t pdo, std::span<const std::uint8_t> payload);
  std::uint8_t pack(std::size_t pdo, std::span<std::uint8_t, 8> out) const {
    return pdos_[pdo].binding.pack_from(image_, out);
  }
  // Whether a PDO carries an object (6010h: TPDO1; 600Ah: RPDO2; ...): PDOs are told apart by what
  // they carry, so a mapping override keeps working.
  bool carries(std::size_t pdo, std::uint16_t index) const;

  // Decoding: pure functions of the profile.
  linebridge_msgs::msg::FeederCode feeder_status(std::uint64_t raw) const { return code(*status_, raw); }
  linebridge_msgs::msg::FeederCode error_condition(std::uint64_t raw) const { return code(*error_condition_, raw); }
  linebridge_msgs::msg::FeederCode control_box_error(std::uint64_t raw) const { return code(*control_box_error_, raw); }
  linebridge_msgs::msg::FeederFunctions functions(std::uint32_t raw) const;
  linebridge_msgs::msg::PickInsertion pick(std::uint8_t raw) const;
  linebridge_msgs::msg::FeederUnwinding unwinding(std::uint32_t raw) const;  // stamp is the caller's
  linebridge_msgs::msg::FeederUnwinding last_unwinding() const;              // from the image (TPDO1)
  // The loom side as the image holds it (received RPDOs, or the bridge's own image).
  // outputs_in_use: the box's RPDO3 (600Dh) exists and is valid, so its outputs mean something.
  void fill_loom(linebridge_msgs::msg::LoomSide& loom, bool outputs_in_use) const;
  void fill_other_values(std::vector<linebridge_msgs::msg::ProcessValue>& out) const { others_->fill(image_, out); }

  // EMCY FF10h: EMCY bytes 3..6 = manufacturer bytes 0..3, little-endian; bit k = feeder k+1.
  static std::uint32_t ff10_bitmap(const std::array<std::uint8_t, 5>& manufacturer);
  static bool in_bitmap(std::uint32_t bitmap, unsigned feeder) {
    return feeder >= 1 && feeder <= kBitmapFeeders && ((bitmap >> (feeder - 1)) & 1U) != 0;
  }

  // Validation: any thread (reads only the profile). count: the feeders the device reported
  // (6009h sub 0), when known.
  Result<Write> command(unsigned feeder, const std::string& name, std::uint8_t manufacturer_code,
                        std::optional<unsigned> count) const;
  Result<Write> test(unsigned feeder, const std::string& name, std::uint8_t parameter,
                     std::optional<unsigned> count) const;
  // 6001h sub feeder: the object to read before merge_functions().
  Result<const profiles::ObjectDef*> functions_object(unsigned feeder, std::optional<unsigned> count) const;
  // `current` with the requested states; refuses unknown functions or states and any change of a
  // function the feeder reports as not available.
  struct FunctionSetting {
    std::string function;
    std::string state;
  };
  Result<std::uint64_t> merge_functions(std::uint64_t current, const std::vector<FunctionSetting>& settings) const;
  Result<Write> number_assignment(unsigned feeder, std::uint8_t number, std::optional<unsigned> count) const;
  Result<Write> color_assignment(unsigned feeder, std::uint8_t color, std::optional<unsigned> count) const;
  Result<Write> weft_insertion_type(const std::string& name) const;
  // 6005h sub 2 from source names; each must be supported (6005h sub 1 as read from the device).
  Result<Write> trigger_sources(const std::vector<std::string>& selected, std::uint64_t supported) const;
  const profiles::ObjectDef& trigger_sources_supported() const { return *supported_; }
  const profiles::ObjectDef& trigger_sources_selected() const { return *selected_; }
  Result<RawLoom> validate(const linebridge_msgs::msg::LoomSetpoint& sp) const;
  // Loop thread: into the RPDO image.
  void apply(const RawLoom& raw);

  // A checked write of any writable profile object (access, type range, printed range, table).
  static Result<Write> checked(const profiles::ObjectDef& object, std::uint64_t raw);
  static linebridge_msgs::msg::FeederCode code(const profiles::ValueTable& table, std::uint64_t raw);

 private:
  struct Object {
    const profiles::ObjectDef* def = nullptr;
    std::size_t slot = canopen::ProcessImage::npos;
  };
  const profiles::ObjectDef& object(std::string_view name) const;
  const profiles::BitSet& bitset(std::string_view name) const;
  const profiles::BitField& field(const profiles::BitSet& set, std::string_view name) const;
  Object bind(std::string_view name);
  Result<const profiles::ObjectDef*> per_feeder(std::string_view array, unsigned feeder,
                                                std::optional<unsigned> count) const;

  const profiles::Profile& profile_;
  canopen::ProcessImage image_;
  const profiles::ValueTable* status_;
  const profiles::ValueTable* error_condition_;
  const profiles::ValueTable* control_box_error_;
  const profiles::BitSet* functions_;
  const profiles::BitSet* unwinding_;
  const profiles::BitSet* weft_filling_;
  const profiles::BitSet* test_;
  const profiles::BitSet* trigger_bits_;
  const profiles::ObjectDef* supported_;
  const profiles::ObjectDef* selected_;
  Object unwinding_time_, loom_status_, weft_filling_word_, trigger_signal_;
  std::array<Object, 5> picks_;
  std::array<Object, kOutputGroups> outputs_;
  std::optional<OtherValues> others_;      // after the typed objects are bound
  std::vector<profiles::DevicePdo> defs_;  // what each PDO is decoded and sent by; never resized
  std::vector<Pdo> pdos_;
  bool loom_seen_ = false;  // an RPDO was received or the image was set
};

}  // namespace lb::gateways
