#include "gateways/corrugator_codec.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;

WordDecoder<msg::CorrugatorStatusWord> CorrugatorTraits::status_word(const profiles::BitSet& set) {
  using W = msg::CorrugatorStatusWord;
  return decoder(NamedBits<W>(set, {{"drive_running", &W::drive_running},
                                    {"drive_ready_to_start", &W::drive_ready_to_start},
                                    {"fault", &W::fault},
                                    {"alarm", &W::alarm},
                                    {"increase_request", &W::increase_request},
                                    {"decrease_request", &W::decrease_request},
                                    {"master_extruder_enabled", &W::master_extruder_enabled},
                                    {"f1_running", &W::f1_running},
                                    {"f1_ready", &W::f1_ready},
                                    {"f2_running", &W::f2_running},
                                    {"f2_ready", &W::f2_ready},
                                    {"f3_running", &W::f3_running},
                                    {"f3_ready", &W::f3_ready},
                                    {"start_cut_pulse", &W::start_cut_pulse}}));
}

WordDecoder<msg::CorrugatorControlWord> CorrugatorTraits::control_word(const profiles::BitSet& set) {
  using W = msg::CorrugatorControlWord;
  return decoder(NamedBits<W>(set, {{"drive_stop", &W::drive_stop},
                                    {"drive_start", &W::drive_start},
                                    {"move_in", &W::move_in},
                                    {"move_out", &W::move_out},
                                    {"extruder_running", &W::extruder_running},
                                    {"f1_stop", &W::f1_stop},
                                    {"f1_start", &W::f1_start},
                                    {"f2_stop", &W::f2_stop},
                                    {"f2_start", &W::f2_start},
                                    {"f3_stop", &W::f3_stop},
                                    {"f3_start", &W::f3_start}}));
}

std::vector<std::string> CorrugatorTraits::momentary_commands() {
  return {"drive_stop", "drive_start", "move_in",  "move_out", "f1_stop",
          "f1_start",   "f2_stop",     "f2_start", "f3_stop",  "f3_start"};
}

template class DriveCodec<CorrugatorTraits>;

}  // namespace lb::gateways
