#pragma once
// CiA 420-3 corrugator (profile version 3.1) as DriveCodec renders it.

#include <string>
#include <string_view>
#include <vector>

#include "gateways/drive_codec.hpp"
#include "msgs/corrugator.h"

namespace lb::gateways {

struct CorrugatorTraits {
  using Status = linebridge_msgs::msg::CorrugatorStatus;
  using StatusWord = linebridge_msgs::msg::CorrugatorStatusWord;
  using ControlWord = linebridge_msgs::msg::CorrugatorControlWord;
  using Setpoint = linebridge_msgs::msg::CorrugatorSetpoint;
  static constexpr std::string_view device = "corrugator";

  static WordDecoder<StatusWord> status_word(const profiles::BitSet& set);
  static WordDecoder<ControlWord> control_word(const profiles::BitSet& set);
  static std::vector<std::string> momentary_commands();
};

extern template class DriveCodec<CorrugatorTraits>;
using CorrugatorCodec = DriveCodec<CorrugatorTraits>;

}  // namespace lb::gateways
