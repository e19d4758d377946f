#pragma once
// The status and control word bits every CiA 420 drive part the bridge knows (puller, 420-2;
// corrugator, 420-3) defines alike: fault, alarm, increase and decrease request (status bits 3-6),
// the extruder-running control bit 6 and the three feedback drives f1-f3 (status bits 8-13,
// control bits 7-12). Written here by hand from the specifications and profile-decisions.md; each
// type's codec test adds the bits of its own (motor/clamp, drive/move, ...).
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "unit/drive_codec_test.hpp"

namespace lb::test {

inline const std::vector<NamedBit> kCia420SharedStatusBits{
    {3, "fault"},    {4, "alarm"},       {5, "increase_request"}, {6, "decrease_request"}, {8, "f1_running"},
    {9, "f1_ready"}, {10, "f2_running"}, {11, "f2_ready"},        {12, "f3_running"},      {13, "f3_ready"}};
inline const std::vector<NamedBit> kCia420SharedControlBits{{6, "extruder_running"}, {7, "f1_stop"},   {8, "f1_start"},
                                                            {9, "f2_stop"},          {10, "f2_start"}, {11, "f3_stop"},
                                                            {12, "f3_start"}};
// The momentary commands among them (extruder running is a level, not a command).
inline const std::vector<std::pair<std::string, unsigned>> kCia420SharedMomentary{{"f1_stop", 7},  {"f1_start", 8},
                                                                                  {"f2_stop", 9},  {"f2_start", 10},
                                                                                  {"f3_stop", 11}, {"f3_start", 12}};

// A type's own bits (or commands) first, then the shared ones: the order the commands are listed in.
template <class T>
std::vector<T> own_then_shared(std::initializer_list<T> own, const std::vector<T>& shared) {
  std::vector<T> all(own);
  all.insert(all.end(), shared.begin(), shared.end());
  return all;
}
inline std::vector<NamedBit> cia420_status_bits(std::initializer_list<NamedBit> own) {
  return own_then_shared(own, kCia420SharedStatusBits);
}
inline std::vector<NamedBit> cia420_control_bits(std::initializer_list<NamedBit> own) {
  return own_then_shared(own, kCia420SharedControlBits);
}
inline std::vector<std::pair<std::string, unsigned>> cia420_momentary(
    std::initializer_list<std::pair<std::string, unsigned>> own) {
  return own_then_shared(own, kCia420SharedMomentary);
}

}  // namespace lb::test
