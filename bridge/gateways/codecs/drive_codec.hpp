#pragma once
// A CiA 420 drive-like device (puller, corrugator, any type whose registry entry says drive)
// rendered as its DDS types: DriveImage holds the PDOs and values; Binding is the type's word
// binding, generated from its IDL (idl/word_bindings.cmake): its message types and the fields of
// its status and control words, which meet the profile's bits by name.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gateways/codecs/drive_image.hpp"
#include "gateways/codecs/named_bits.hpp"
#include "msgs/word_bindings.hpp"

namespace lb::gateways {

// Decodes a raw word into the boolean (and enum) fields of a message; bit positions come from the
// profile at start-up.
template <class Word>
using WordDecoder = std::function<void(std::uint64_t raw, Word& word)>;

template <class Word>
WordDecoder<Word> decoder(NamedBits<Word> bits) {
  return [bits = std::move(bits)](std::uint64_t raw, Word& word) { bits.decode(raw, word); };
}

// The flags of `flags` by the profile's bit positions, and each field of `codes` by the name the
// profile gives its code (a profile without the field: the IDL's first enumerator, "not reported").
template <class Word, class Flags, class Codes>
WordDecoder<Word> word_decoder(const profiles::BitSet& set, const Flags& flags, const Codes& codes) {
  struct Code {
    std::optional<profiles::BitField> field;
    void (*set)(Word&, std::string_view);
  };
  std::vector<Code> bound;
  for (const auto& c : codes) {
    const auto* f = set.field(c.name);
    bound.push_back({f != nullptr ? std::optional(*f) : std::nullopt, c.set});
  }
  return [bits = NamedBits<Word>(set, flags), bound = std::move(bound)](std::uint64_t raw, Word& w) {
    bits.decode(raw, w);
    for (const auto& c : bound) c.set(w, c.field ? c.field->values.name(c.field->extract(raw)).value_or("") : "");
  };
}

// The control bits of a binding pressed like buttons (its control word's flags its setpoint does
// not carry as a state).
template <class Binding>
std::vector<std::string> momentary_commands() {
  return {Binding::momentary.begin(), Binding::momentary.end()};
}

template <class Binding>
class DriveCodec : public DriveImage {
 public:
  using Status = typename Binding::Status;
  using Setpoint = typename Binding::Setpoint;

  DriveCodec(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos,
             SetEchoMonitor::Settings echo = {}, bool rpdos_received = false)
      : DriveImage(profile, pdos, profile.device, echo, rpdos_received),
        status_word_(word_decoder<typename Binding::StatusWord>(bitset("status_word"), Binding::status_flags,
                                                                Binding::status_codes)),
        control_word_(word_decoder<typename Binding::ControlWord>(bitset("control_word"), Binding::control_flags,
                                                                  Binding::control_codes)) {}

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
  WordDecoder<typename Binding::StatusWord> status_word_;
  WordDecoder<typename Binding::ControlWord> control_word_;
};

}  // namespace lb::gateways
