#pragma once
// Records every frame a bus carries, received and sent, to a file in can-utils' log format (the
// format of `candump -l`), so the recording replays in canplayer, in a log: bus, and reads in any
// tool that reads candump logs. A decorator: the bus below works exactly as without it.
//
// The file is opened for appending (a restart adds to it). The bus loop only formats a frame's
// line into a buffer; a thread of the recording writes the buffer out (whole lines, so a reader
// such as tail -f sees whole lines), so a slow or stuck disk never stalls the loop. The buffer is
// bounded (kBufferBytes): a frame that does not fit, or cannot be written (disk full), is counted
// in BusStats::record_errors and the bus goes on. A crash loses at most what the buffer held.
// Sent frames are recorded once the bus accepted them, with the time of sending.

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "can/bus.hpp"
#include "can/unique_fd.hpp"

namespace lb::can {

class RecordingBus final : public Bus {
  struct PrivateTag {
    explicit PrivateTag() = default;
  };

 public:
  // The interface name in the lines: the ifname of a socketcan: bus, the name of a virtual: bus,
  // "log" for a replay. inner must not be null.
  static Result<std::unique_ptr<RecordingBus>> open(std::unique_ptr<Bus> inner, const std::string& path);

  static constexpr std::size_t kBufferBytes = 4 << 20;

  RecordingBus(PrivateTag, std::unique_ptr<Bus> inner, UniqueFd file, std::string interface);
  // Writes out what the buffer holds (for a disk that takes it within a second), then stops.
  ~RecordingBus() override;

  const std::string& uri() const override { return inner_->uri(); }
  int fd() const override { return inner_->fd(); }
  Result<std::optional<CanFrame>> receive() override;
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override;

 private:
  void record(const CanFrame& frame);
  void write_out();

  std::unique_ptr<Bus> inner_;
  UniqueFd file_;
  std::string interface_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::string buffer_;                        // guarded by mutex_
  bool stopping_ = false;                     // guarded by mutex_
  std::atomic<std::uint64_t> record_errors_{0};
  std::thread writer_;
};

}  // namespace lb::can
