#pragma once
// A CiA 420 drive (puller, corrugator) rendered as its DDS types: DriveImage holds the PDOs and
// values; Traits names the device (object prefix), its message types and how its status and
// control words map onto them. Traits:
//   using Status, StatusWord, ControlWord, Setpoint;          // generated DDS types
//   static constexpr std::string_view device;                // "puller", "corrugator"
//   static WordDecoder<StatusWord> status_word(const profiles::BitSet&);
//   static WordDecoder<ControlWord> control_word(const profiles::BitSet&);
//   static std::vector<std::string> momentary_commands();    // control bits pressed like buttons

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gateways/drive_image.hpp"
#include "gateways/named_bits.hpp"

namespace lb::gateways {

// Decodes a raw word into the boolean (and enum) fields of a message; bit positions come from the
// profile at start-up.
template <class Word>
using WordDecoder = std::function<void(std::uint64_t raw, Word& word)>;

template <class Word>
WordDecoder<Word> decoder(NamedBits<Word> bits) {
  return [bits = std::move(bits)](std::uint64_t raw, Word& word) { bits.decode(raw, word); };
}

template <class Traits>
class DriveCodec : public DriveImage {
 public:
  using Status = typename Traits::Status;
  using Setpoint = typename Traits::Setpoint;
  using DeviceTraits = Traits;

  DriveCodec(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos,
             SetEchoMonitor::Settings echo = {}, bool rpdos_received = false)
      : DriveImage(profile, pdos, Traits::device, echo, rpdos_received),
        status_word_(Traits::status_word(bitset("status_word"))),
        control_word_(Traits::control_word(bitset("control_word"))) {}

  // Everything the image holds, in engineering units (stamp, health, length errors are the caller's).
  void fill(Status& s) const {
    const std::uint64_t sw = status_word();
    s.status_word().raw(static_cast<std::uint16_t>(sw));
    status_word_(sw, s.status_word());
    s.speed_actual_percent(speed_actual_percent());
    s.load_actual_percent(load_actual_percent());
    s.speed_set_echo_percent(speed_set_echo_percent());
    s.product_speed_m_per_min(product_speed_m_per_min());
    const auto manufacturer = manufacturer_status_word();
    s.manufacturer_status_word_present(manufacturer.has_value());
    s.manufacturer_status_word(manufacturer.value_or(0));
    const std::uint64_t cw = control_word();
    s.control_word().raw(static_cast<std::uint16_t>(cw));
    control_word_(cw, s.control_word());
    s.speed_set_percent(speed_set_percent());
    s.set_echo_mismatch(set_echo_mismatch());
    fill_other_values(s.other_values());
  }

  Result<RawSetpoint> validate(const Setpoint& sp) const {
    return DriveImage::validate(sp.extruder_running(), sp.speed_set_percent());
  }

 private:
  WordDecoder<typename Traits::StatusWord> status_word_;
  WordDecoder<typename Traits::ControlWord> control_word_;
};

}  // namespace lb::gateways
