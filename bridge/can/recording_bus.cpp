#include "can/recording_bus.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <chrono>

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
    : inner_(std::move(inner)), file_(std::move(file)), interface_(std::move(interface)) {
  buffer_.reserve(64 << 10);
  writer_ = std::thread([this] { write_out(); });
}

RecordingBus::~RecordingBus() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  writer_.join();
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
  s.record_errors += record_errors_;
  return s;
}

void RecordingBus::record(const CanFrame& frame) {
  const std::string line = format_log_line(frame, interface_);
  {
    std::lock_guard lock(mutex_);
    if (buffer_.size() + line.size() > kBufferBytes) {
      ++record_errors_;
      return;
    }
    buffer_ += line;
  }
  cv_.notify_one();
}

// The writer: takes the whole buffer at once, writes it, and repeats. Non-blocking writes with a
// poll, so that a recording to a reader that never reads (a FIFO) still lets the bridge stop: at
// the stop it gives up after a second and counts what it could not write.
void RecordingBus::write_out() {
  std::string chunk;
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait(lock, [this] { return !buffer_.empty() || stopping_; });
    if (buffer_.empty() && stopping_) return;
    chunk.clear();
    chunk.swap(buffer_);
    const bool stopping = stopping_;
    lock.unlock();
    std::size_t done = 0;
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(1);
    while (done < chunk.size()) {
      const ssize_t n = ::write(file_.get(), chunk.data() + done, chunk.size() - done);
      if (n > 0) {
        done += static_cast<std::size_t>(n);
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        bool stop_now = false;
        {
          std::lock_guard check(mutex_);
          stop_now = stopping_;
        }
        if (stop_now && std::chrono::steady_clock::now() > give_up) break;
        pollfd p{file_.get(), POLLOUT, 0};
        ::poll(&p, 1, 100);
        continue;
      }
      break;  // disk full, I/O error: what is left of the chunk is lost
    }
    if (done < chunk.size()) {
      record_errors_ += static_cast<std::uint64_t>(std::count(chunk.begin() + static_cast<std::ptrdiff_t>(done), chunk.end(), '\n'));
    }
    lock.lock();
    if (stopping && buffer_.empty()) return;
  }
}

}  // namespace lb::can
