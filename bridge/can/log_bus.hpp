#pragma once
// A recorded bus played back: the frames of a can-utils log file (candump -l, or record: of this
// gateway) arrive as if from the wire, at the recorded pace or as fast as the reader takes them.
// For analysing a line offline and reproducing a problem at a desk.
//
// URI: log:<path>[?pace=realtime|fast][&interface=<name>]
//   pace=realtime (default)  frame n arrives (t_n - t_0) after the first receive()
//   pace=fast                 frames arrive as fast as they are read, in batches, so a bus loop
//                             still serves its timers and posted work in between
//   interface=<name>          only the lines of that interface (a `candump -l any` recording)
// The path is everything up to the first '?'. Frames keep their recorded timestamps.
//
// A recording cannot be changed by transmitting into it: send() always fails (counted in
// tx_dropped), exactly like ListenOnlyBus, so a bridge runs such a bus in the monitor role.
// Lines that are not classical CAN frames make receive() fail once with file:line and the reason;
// the next receive() goes on after that line. At the end of the file the bus falls silent and its
// state becomes `down`; error frames in the recording drive the state before that.

#include <chrono>
#include <fstream>
#include <memory>
#include <optional>
#include <string_view>

#include "can/bus.hpp"
#include "can/candump_log.hpp"
#include "can/unique_fd.hpp"

namespace lb::can {

class LogBus final : public Bus {
  struct PrivateTag {
    explicit PrivateTag() = default;
  };

 public:
  enum class Pace { realtime, fast };
  struct Spec {
    std::string path;
    Pace pace = Pace::realtime;
    std::string interface;  // empty: every line
  };

  // The part after "log:". Checks the syntax only (the configuration uses it to point at the key).
  static Result<Spec> parse_spec(std::string_view spec);
  // Opens the file and reads its first frame, so a file that is not a log fails here.
  static Result<std::unique_ptr<LogBus>> open(std::string_view spec);

  LogBus(PrivateTag, std::string uri, Spec spec, std::ifstream in, UniqueFd timer);

  const std::string& uri() const override { return uri_; }
  // A timerfd: readable when the next frame is due.
  int fd() const override { return timer_.get(); }
  Result<std::optional<CanFrame>> receive() override;
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override { return stats_; }

  // True once every frame of the file was delivered.
  bool finished() const { return !pending_ && eof_; }

 private:
  void read_next();  // fills pending_, or sets eof_; remembers the first bad line in bad_line_
  void wake_at(std::chrono::steady_clock::time_point when);

  std::string uri_;
  Spec spec_;
  std::ifstream in_;
  UniqueFd timer_;
  std::optional<CanFrame> pending_;
  bool eof_ = false;
  std::optional<Error> bad_line_;
  int fast_budget_ = 0;
  std::uint64_t line_no_ = 0;
  std::optional<std::chrono::steady_clock::time_point> start_;  // replay clock, set at first receive
  std::int64_t first_ns_ = 0;                                   // recorded time of the first frame
  BusStats stats_;
};

}  // namespace lb::can
