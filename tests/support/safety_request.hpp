#pragma once
// One request of the safety table's operator as the judge reads it (safety_judge.hpp): what it
// was, when it was written (realtime, the clock the bus stamps frames with), its answer, and for
// a stop the frames that show it on the bus.

#include <cstdint>
#include <string>
#include <vector>

#include "support/safety_device.hpp"

namespace lb::test::safety {

struct OperatorRequest {
  enum class Kind {
    enabling_on,   // a set value with an enabling level on
    enabling_off,  // a set value with every enabling level off: a stop
    stopping,      // the profile's stopping command (or the feeder's stop_mode): a stop
    nmt_stop,      // NMT stop: a stop
    nmt_start,     // NMT start: releases an operator's stop, resumes the set values in force
    other,         // anything else (an NMT reset, ...)
  };
  Kind kind = Kind::other;
  std::string what;
  std::int64_t written_ns = 0;   // realtime, just before the request was written
  std::int64_t answered_ns = 0;  // 0: no answer within the deadline
  bool accepted = false;
  std::string reason;
  std::vector<FrameProof> proofs;  // a stop: the frames that show it on the bus

  bool stops() const { return kind == Kind::enabling_off || kind == Kind::stopping || kind == Kind::nmt_stop; }
};

}  // namespace lb::test::safety
