#include "gateways/puller_codec.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;

WordDecoder<msg::PullerStatusWord> PullerTraits::status_word(const profiles::BitSet& set) {
  using W = msg::PullerStatusWord;
  NamedBits<W> bits(set, {{"motor_running", &W::motor_running},
                          {"motor_ready_to_start", &W::motor_ready_to_start},
                          {"clamp_closed", &W::clamp_closed},
                          {"fault", &W::fault},
                          {"alarm", &W::alarm},
                          {"increase_request", &W::increase_request},
                          {"decrease_request", &W::decrease_request},
                          {"reverse_direction", &W::reverse_direction},
                          {"f1_running", &W::f1_running},
                          {"f1_ready", &W::f1_ready},
                          {"f2_running", &W::f2_running},
                          {"f2_ready", &W::f2_ready},
                          {"f3_running", &W::f3_running},
                          {"f3_ready", &W::f3_ready}});
  // Version 3.0 only: a one-bit field with named codes. Looked up by code name, so an override
  // that inverts the bit's meaning is followed too.
  const auto* mode = set.field("speed_set_mode");
  if (mode == nullptr || mode->width != 1) {
    return [bits = std::move(bits)](std::uint64_t raw, W& w) {
      bits.decode(raw, w);
      w.speed_set_mode(msg::PULLER_SPEED_SET_NOT_REPORTED);
    };
  }
  return [bits = std::move(bits), field = *mode](std::uint64_t raw, W& w) {
    bits.decode(raw, w);
    const auto name = field.values.name(field.extract(raw));
    w.speed_set_mode(name == "remote"  ? msg::PULLER_SPEED_SET_REMOTE
                     : name == "local" ? msg::PULLER_SPEED_SET_LOCAL
                                       : msg::PULLER_SPEED_SET_NOT_REPORTED);
  };
}

WordDecoder<msg::PullerControlWord> PullerTraits::control_word(const profiles::BitSet& set) {
  using W = msg::PullerControlWord;
  return decoder(NamedBits<W>(set, {{"motor_stop", &W::motor_stop},
                                    {"motor_start", &W::motor_start},
                                    {"clamp_close", &W::clamp_close},
                                    {"clamp_open", &W::clamp_open},
                                    {"extruder_running", &W::extruder_running},
                                    {"f1_stop", &W::f1_stop},
                                    {"f1_start", &W::f1_start},
                                    {"f2_stop", &W::f2_stop},
                                    {"f2_start", &W::f2_start},
                                    {"f3_stop", &W::f3_stop},
                                    {"f3_start", &W::f3_start}}));
}

std::vector<std::string> PullerTraits::momentary_commands() {
  return {"motor_stop", "motor_start", "clamp_close", "clamp_open", "f1_stop",
          "f1_start",   "f2_stop",     "f2_start",    "f3_stop",    "f3_start"};
}

template class DriveCodec<PullerTraits>;

}  // namespace lb::gateways
