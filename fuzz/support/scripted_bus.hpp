#pragma once
// A bus for fuzzing what runs on a bus loop: it hands the loop a script of frames, runs the
// script's actions (requests of the code under test) on the loop thread between them, keeps what
// the loop sends, and tells the fuzzer when the script is done. No sockets, no other process.
// After an action the bus stays silent until the work the action posted has run, so requests and
// answers interleave exactly as the script orders them (the loop would otherwise drain the whole
// script before running posted work).

#include <sys/eventfd.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <future>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "can/bus.hpp"
#include "can/unique_fd.hpp"
#include "canopen/bus_loop.hpp"

namespace lb::fuzz {

class ScriptedBus final : public can::Bus {
 public:
  struct Step {
    std::optional<can::CanFrame> frame;
    std::function<void()> action;  // when there is no frame
  };

  explicit ScriptedBus(std::vector<Step> steps)
      : steps_(std::move(steps)), event_(::eventfd(1, EFD_NONBLOCK | EFD_CLOEXEC)) {}

  // Before the loop starts: the loop that owns this bus.
  void attach(canopen::BusLoop& loop) { loop_ = &loop; }
  // Resolved on the loop thread once every step has run.
  std::future<void> finished() { return finished_.get_future(); }
  // Read after the loop stopped.
  const std::vector<can::CanFrame>& sent() const { return sent_; }

  const std::string& uri() const override { return uri_; }
  int fd() const override { return event_.get(); }
  Result<std::optional<can::CanFrame>> receive() override {
    while (next_ < steps_.size()) {
      auto& step = steps_[next_++];
      if (step.frame) return step.frame;
      step.action();
      silence();
      loop_->post([this] { readable(); });
      return std::optional<can::CanFrame>{};
    }
    if (!done_) {
      silence();  // the loop waits for its posted work and timers only
      done_ = true;
      finished_.set_value();
    }
    return std::optional<can::CanFrame>{};
  }
  Result<void> send(const can::CanFrame& frame) override {
    sent_.push_back(frame);
    return {};
  }
  can::BusStats stats() const override { return {}; }

 private:
  void silence() {
    std::uint64_t count = 0;
    [[maybe_unused]] const auto n = ::read(event_.get(), &count, sizeof count);
  }
  void readable() {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(event_.get(), &one, sizeof one);
  }

  canopen::BusLoop* loop_ = nullptr;
  std::string uri_ = "scripted:fuzz";
  std::vector<Step> steps_;
  std::size_t next_ = 0;
  can::UniqueFd event_;
  bool done_ = false;
  std::promise<void> finished_;
  std::vector<can::CanFrame> sent_;
};

// A frame of the given identifier with up to 8 bytes of fuzzer data; DLC as the fuzzer says.
template <class Provider>
can::CanFrame fuzzed_frame(Provider& in, std::uint32_t id) {
  can::CanFrame f;
  f.id = id;
  f.len = in.template ConsumeIntegralInRange<std::uint8_t>(0, can::CanFrame::kMaxLen);
  for (std::uint8_t i = 0; i < f.len; ++i) f.data[i] = in.template ConsumeIntegral<std::uint8_t>();
  return f;
}

// Runs the loop until the script is done and the work it posted has run, then stops it.
inline void run_script(canopen::BusLoop& loop, ScriptedBus& bus) {
  auto finished = bus.finished();
  bus.attach(loop);
  loop.start();
  finished.wait();
  std::promise<void> idle;
  auto settled = idle.get_future();
  loop.post([&idle] { idle.set_value(); });  // posted work runs in order: this comes last
  settled.wait();
  loop.stop();
}

}  // namespace lb::fuzz
