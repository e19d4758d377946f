#include "can/recording_bus.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <string_view>

#include "can/candump_log.hpp"
#include "can/detail.hpp"

namespace lb::can {
namespace {

std::string interface_name(const std::string& uri) {
  const auto colon = uri.find(':');
  const std::string scheme = uri.substr(0, colon);
  if (colon == std::string::npos || scheme == "log") return "log";
  return uri.substr(colon + 1);
}

}  // namespace

Result<std::unique_ptr<RecordingBus>> RecordingBus::open(std::unique_ptr<Bus> inner, const std::string& path) {
  if (!inner) return make_error("record " + path + ": no bus to record");
  // Non-blocking, so the writer thread can give up on a reader that never reads (a FIFO) at a stop;
  // regular files ignore the flag. A FIFO is opened read-write (Linux): a write-only open would
  // wait for a reader (or fail without one), and the bridge must start all the same.
  struct stat st {};
  const bool fifo = ::stat(path.c_str(), &st) == 0 && S_ISFIFO(st.st_mode);
  UniqueFd file{fifo ? ::open(path.c_str(), O_RDWR | O_CLOEXEC | O_NONBLOCK)
                     : ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC | O_NONBLOCK, 0644)};
  if (!file) return make_error(inner->uri() + ": cannot open the recording " + path + ": " + detail::errno_text(errno));
  std::string name = interface_name(inner->uri());
  return std::make_unique<RecordingBus>(PrivateTag{}, std::move(inner), std::move(file), std::move(name));
}

RecordingBus::RecordingBus(PrivateTag, std::unique_ptr<Bus> inner, UniqueFd file, std::string interface)
    : inner_(std::move(inner)), interface_(std::move(interface)), shared_(std::make_shared<Shared>(std::move(file))) {
  static_assert((kBufferBytes & (kBufferBytes - 1)) == 0);
  line_.reserve(interface_.size() + 64);  // the longest line: timestamp, identifier, 8 data bytes
  writer_ = std::thread([s = shared_] { write_out(*s); });
}

RecordingBus::~RecordingBus() {
  Shared& s = *shared_;
  std::unique_lock lock(s.stop_mutex);
  s.stopping = true;
  s.stop_cv.notify_all();
  // The writer gives up by itself after kStopWait, unless a write() never returns: then it is left
  // to finish on its own (it holds the file and the ring), and the shutdown goes on.
  const bool finished = s.stop_cv.wait_for(lock, kStopWait + kStopGrace, [&s] { return s.finished; });
  lock.unlock();
  if (finished) {
    writer_.join();
  } else {
    writer_.detach();  // what the ring still holds is lost with it
  }
}

Result<std::optional<CanFrame>> RecordingBus::receive() {
  auto r = inner_->receive();
  if (r && r->has_value()) record(**r);
  return r;
}

Result<void> RecordingBus::send(const CanFrame& frame) {
  // Stamped as it is handed to the bus, as the PDO transmitter stamps what it reports (a press's
  // duration): read after the send, the two clocks would be apart by whatever the scheduler put
  // between them (milliseconds on a loaded machine).
  CanFrame sent = frame;
  sent.timestamp_ns = detail::realtime_ns();
  auto r = inner_->send(frame);
  if (r) record(sent);
  return r;
}

BusStats RecordingBus::stats() const {
  BusStats s = inner_->stats();
  s.record_errors += shared_->record_errors;
  return s;
}

// The loop's side: no lock, no system call, no allocation.
void RecordingBus::record(const CanFrame& frame) {
  Shared& s = *shared_;
  line_.clear();
  append_log_line(line_, frame, interface_);
  const std::string_view line = line_;
  const std::uint64_t put = s.put.load(std::memory_order_relaxed);
  const std::uint64_t taken = s.taken.load(std::memory_order_acquire);
  if (kBufferBytes - (put - taken) < line.size()) {
    ++s.record_errors;
    return;
  }
  const std::size_t at = put & (kBufferBytes - 1);
  const std::size_t first = std::min(line.size(), kBufferBytes - at);
  std::copy_n(line.data(), first, s.ring.data() + at);
  std::copy_n(line.data() + first, line.size() - first, s.ring.data());
  s.put.store(put + line.size(), std::memory_order_release);
}

bool RecordingBus::stop_requested(Shared& s) {
  std::lock_guard lock(s.stop_mutex);
  return s.stopping;
}

// The writer: every kWriteInterval (or at the stop) writes out what the loop put into the ring.
void RecordingBus::write_out(Shared& s) {
  for (;;) {
    // Read before draining, so that everything recorded before the stop is written (or counted).
    const bool stopping = stop_requested(s);
    drain(s, stopping);
    std::unique_lock lock(s.stop_mutex);
    if (stopping) {
      s.finished = true;
      s.stop_cv.notify_all();
      return;
    }
    s.stop_cv.wait_for(lock, kWriteInterval, [&s] { return s.stopping; });
  }
}

// Non-blocking writes with a poll, so that a recording to a reader that never reads (a FIFO) still
// lets the bridge stop. The stop is bounded by kStopWait from the moment it is requested, checked
// before every write: a file that takes nothing and one that takes a trickle (a slow disk, whose
// writes never say EAGAIN) alike. What is left then is dropped and counted.
void RecordingBus::drain(Shared& s, bool stopping) {
  using Clock = std::chrono::steady_clock;
  auto give_up = stopping ? Clock::now() + kStopWait : Clock::time_point::max();
  for (;;) {
    const std::uint64_t taken = s.taken.load(std::memory_order_relaxed);
    const std::uint64_t put = s.put.load(std::memory_order_acquire);
    if (taken == put) return;
    if (!stopping && stop_requested(s)) {
      stopping = true;
      give_up = Clock::now() + kStopWait;
    }
    const auto now = Clock::now();
    if (now >= give_up) {
      drop(s, taken, put);
      return;
    }
    const std::size_t at = taken & (kBufferBytes - 1);
    const std::size_t len = static_cast<std::size_t>(std::min<std::uint64_t>(put - taken, kBufferBytes - at));
    const ssize_t n = ::write(s.file.get(), s.ring.data() + at, len);
    if (n > 0) {
      s.taken.store(taken + static_cast<std::uint64_t>(n), std::memory_order_release);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      // Wakes at least every 100 ms to notice a stop; never sleeps past the deadline.
      const auto left = std::chrono::ceil<std::chrono::milliseconds>(give_up - now);
      pollfd p{s.file.get(), POLLOUT, 0};
      ::poll(&p, 1, static_cast<int>(std::min<std::int64_t>(100, left.count())));
      continue;
    }
    drop(s, taken, put);  // disk full, I/O error: what the ring holds now is lost; later lines try again
    return;
  }
}

void RecordingBus::drop(Shared& s, std::uint64_t from, std::uint64_t to) {
  std::uint64_t lines = 0;
  for (std::uint64_t i = from; i != to; ++i) lines += s.ring[i & (kBufferBytes - 1)] == '\n' ? 1 : 0;
  s.record_errors += lines;
  s.taken.store(to, std::memory_order_release);
}

}  // namespace lb::can
