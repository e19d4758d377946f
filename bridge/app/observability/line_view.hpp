#pragma once
// What the observability server (http_server.hpp) shows of a line: the newest diagnostics sample
// the bus process sent (rt/<line>/bridge/diagnostics, once a second) and the DDS process's own
// numbers. The DDS process's relay loop writes it (LineViewKeeper::set, 1 Hz); the server's threads
// read it. Nothing here is a command: the view is a copy, and the page and the metrics are made
// from it alone (render_status_page, render_metrics: pure functions of a LineView).

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "dds/discovery_gate.hpp"
#include "msgs/common.h"

namespace lb::app::obs {

struct LineView {
  using Clock = std::chrono::steady_clock;

  std::string line;  // the line file's name of the line (known before the first sample)
  // The newest diagnostics sample; null before the first (the bus process not connected yet, or a
  // standby's bus process that has not let this DDS side in).
  std::shared_ptr<const linebridge_msgs::msg::Diagnostics> diagnostics;
  Clock::time_point received{};  // when `diagnostics` arrived
  Clock::time_point now{};       // when this view was taken: ages are measured against it

  // The DDS process itself.
  bool connected = false;  // let in by its bus process (the channel serves it)
  Clock::time_point connected_since{};
  std::uint64_t samples_published = 0;            // samples of the bus process written to DDS
  std::uint64_t samples_not_forwarded = 0;        // set values and requests the bus process could not take in time
  std::uint32_t remote_participants = 0;          // DDS participants this process knows now (clients)
  std::uint64_t remote_participants_refused = 0;  // failed authentication since start (secured line)
  std::uint64_t remote_participants_departed = 0;
  bool secured = false;   // DDS Security in force
  ddsl::GateCounts gate;  // the discovery gate (all zero without one)

  // Seconds since the newest diagnostics sample arrived; -1 before the first.
  double diagnostics_age_s() const {
    if (!diagnostics) return -1.0;
    return std::chrono::duration<double>(now - received).count();
  }
};

// The one place the relay loop and the server's threads meet: a mutex held for a copy of a few
// numbers and a shared_ptr, never while a page is made, so a reader never holds the relay loop
// for longer than that.
class LineViewKeeper {
 public:
  explicit LineViewKeeper(std::string line) { view_.line = std::move(line); }

  void set(const LineView& view) {
    std::lock_guard lock(mutex_);
    view_ = view;
  }
  // Changes part of the view under the lock (the relay loop's own numbers, a new sample).
  template <class Change>
  void update(Change&& change) {
    std::lock_guard lock(mutex_);
    change(view_);
  }
  LineView get() const {
    LineView copy;
    {
      std::lock_guard lock(mutex_);
      copy = view_;
    }
    copy.now = LineView::Clock::now();
    return copy;
  }

 private:
  mutable std::mutex mutex_;
  LineView view_;
};

}  // namespace lb::app::obs
