#pragma once
// CiA 420-2 puller (profile versions 1.0 and 3.0-status) as DriveCodec renders it: one message
// shape for both versions; a bit a version lacks stays false.

#include <string>
#include <string_view>
#include <vector>

#include "gateways/drive_codec.hpp"
#include "msgs/puller.h"

namespace lb::gateways {

struct PullerTraits {
  using Status = linebridge_msgs::msg::PullerStatus;
  using StatusWord = linebridge_msgs::msg::PullerStatusWord;
  using ControlWord = linebridge_msgs::msg::PullerControlWord;
  using Setpoint = linebridge_msgs::msg::PullerSetpoint;
  static constexpr std::string_view device = "puller";

  static WordDecoder<StatusWord> status_word(const profiles::BitSet& set);
  static WordDecoder<ControlWord> control_word(const profiles::BitSet& set);
  static std::vector<std::string> momentary_commands();
};

extern template class DriveCodec<PullerTraits>;
using PullerCodec = DriveCodec<PullerTraits>;

}  // namespace lb::gateways
