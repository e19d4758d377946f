#pragma once
// Records every frame a bus carries, received and sent, to a file in can-utils' log format (the
// format of `candump -l`), so the recording replays in canplayer, in a log: bus, and reads in any
// tool that reads candump logs. A decorator: the bus below works exactly as without it.
//
// The file is opened for appending (a restart adds to it). The bus loop only formats a frame's
// line into a ring; a thread of the recording writes the ring out, so a slow or stuck disk never
// stalls the loop. The two share no lock: the loop may run at realtime priority (realtime_priority:)
// and the writer does not, so a lock between them let the writer, preempted while holding it, hold
// the loop up (SYNCs 1.0-1.3 ms late every ~2 s with a slow disk, BENCHMARKS.md). The ring is
// allocated and touched at open, and the line is formatted into a buffer of the loop's that keeps
// its capacity, so recording a frame neither allocates nor page-faults (bench-record-handoff). It is bounded
// (kBufferBytes): a frame that does not fit, or cannot be written (disk full), is counted in
// BusStats::record_errors and the bus goes on. The writer looks for new lines every kWriteInterval,
// so a crash loses at most what the ring held. Sent frames are recorded once the bus accepted them,
// with the time of sending. The stop is bounded too: the writer gets kStopWait to write out the
// ring and drops (counts) the rest, and a writer whose write() does not return is left behind
// after kStopGrace more, so no file can hold up the bridge's shutdown.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

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

  static constexpr std::size_t kBufferBytes = 4 << 20;  // a power of two: positions wrap by masking
  static constexpr std::chrono::milliseconds kWriteInterval{20};
  // How long the destructor lets the writer write out what the ring holds; the rest is dropped
  // and counted, so a file that takes nothing or a trickle (a FIFO nobody reads, or reads slowly)
  // cannot hold up the bridge's shutdown.
  static constexpr std::chrono::milliseconds kStopWait{1000};
  // Beyond kStopWait, how long the destructor waits for a write() that does not return (a file
  // whose writes block: a hung network file system, a blocking FIFO nobody reads). Then it leaves
  // the writer behind, detached: the writer owns its state, which goes when it returns.
  static constexpr std::chrono::milliseconds kStopGrace{500};

  RecordingBus(PrivateTag, std::unique_ptr<Bus> inner, UniqueFd file, std::string interface);
  // Writes out what the buffer holds for at most kStopWait (kStopWait + kStopGrace if a write
  // blocks), then stops.
  ~RecordingBus() override;

  const std::string& uri() const override { return inner_->uri(); }
  int fd() const override { return inner_->fd(); }
  Result<std::optional<CanFrame>> receive() override;
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override;

 private:
  // What the writer thread uses, owned jointly with it: a writer stuck in write() at the stop is
  // detached and keeps this alive (file and ring) until its write returns, however long after.
  struct Shared {
    explicit Shared(UniqueFd f) : file(std::move(f)), ring(kBufferBytes, '\0') {}
    UniqueFd file;
    // Single producer (the bus loop), single consumer (the writer): positions count bytes since open.
    std::vector<char> ring;
    std::atomic<std::uint64_t> put{0};    // written by the loop only
    std::atomic<std::uint64_t> taken{0};  // written by the writer only
    std::atomic<std::uint64_t> record_errors{0};
    // Between the writer and the destructor only; the loop never takes it.
    std::mutex stop_mutex;
    std::condition_variable stop_cv;
    bool stopping = false;  // guarded by stop_mutex
    bool finished = false;  // guarded by stop_mutex: the writer returned
  };

  void record(const CanFrame& frame);
  static void write_out(Shared& s);
  // Writes what the ring holds; at a stop, gives up kStopWait after the stop was requested.
  static void drain(Shared& s, bool stopping);
  // Counts the lines in [from, to) of the ring as lost and drops them.
  static void drop(Shared& s, std::uint64_t from, std::uint64_t to);
  static bool stop_requested(Shared& s);

  std::unique_ptr<Bus> inner_;
  std::string interface_;
  std::string line_;  // the loop's: the frame being recorded
  std::shared_ptr<Shared> shared_;
  std::thread writer_;
};

}  // namespace lb::can
