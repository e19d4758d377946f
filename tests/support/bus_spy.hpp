#pragma once
// A passive member of a virtual bus for tests: records every frame the others send, and can inject
// frames of its own (a misbehaving node, an EMCY, a raw SDO request).

#include <poll.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "support/eventually.hpp"

namespace lb::test {

class BusSpy {
 public:
  explicit BusSpy(const std::string& uri) : bus_(lb::can::open_bus(uri).value()) {
    thread_ = std::thread([this] {
      while (!stop_) {
        pollfd p{bus_->fd(), POLLIN, 0};
        if (::poll(&p, 1, 50) <= 0) continue;
        std::lock_guard lock(m_);
        while (true) {
          auto r = bus_->receive();
          if (!r || !r->has_value()) break;
          frames_.push_back(**r);
          if (watcher_) watcher_(frames_.back());
        }
      }
    });
  }
  ~BusSpy() {
    stop_ = true;
    thread_.join();
  }
  BusSpy(const BusSpy&) = delete;
  BusSpy& operator=(const BusSpy&) = delete;

  std::vector<lb::can::CanFrame> frames() {
    std::lock_guard lock(m_);
    return frames_;
  }
  std::vector<lb::can::CanFrame> frames(std::uint32_t id) {
    std::vector<lb::can::CanFrame> out;
    for (const auto& f : frames()) {
      if (f.id == id) out.push_back(f);
    }
    return out;
  }
  // Waits (up to a generous deadline) until the frames seen since the last clear() satisfy `done`;
  // false when they never did.
  bool wait_until(const std::function<bool(const std::vector<lb::can::CanFrame>&)>& done,
                  std::chrono::steady_clock::duration timeout = std::chrono::seconds(30)) {
    return eventually(timeout, [&] { return done(frames()); });
  }
  // Waits until `count` frames of `id` were seen since the last clear(); returns those seen.
  std::vector<lb::can::CanFrame> wait_count(std::uint32_t id, std::size_t count,
                                            std::chrono::steady_clock::duration timeout = std::chrono::seconds(30)) {
    eventually(timeout, [&] { return frames(id).size() >= count; });
    return frames(id);
  }
  void clear() {
    std::lock_guard lock(m_);
    frames_.clear();
  }
  // Called on the spy's thread with every frame as it is recorded, for a test that must act within
  // a frame's time of something on the bus (stall a device at the first request of a boot); the
  // watcher must not call back into the spy. Replaces the previous one; an empty one removes it.
  void watch(std::function<void(const lb::can::CanFrame&)> watcher) {
    std::lock_guard lock(m_);
    watcher_ = std::move(watcher);
  }
  lb::Result<void> send(const lb::can::CanFrame& f) {
    std::lock_guard lock(m_);
    return bus_->send(f);
  }

 private:
  std::unique_ptr<lb::can::Bus> bus_;
  std::mutex m_;
  std::vector<lb::can::CanFrame> frames_;
  std::function<void(const lb::can::CanFrame&)> watcher_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace lb::test
