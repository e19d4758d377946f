#include "can/recording_bus.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>

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
  UniqueFd file{::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644)};
  if (!file) return make_error(inner->uri() + ": cannot open the recording " + path + ": " + detail::errno_text(errno));
  std::string name = interface_name(inner->uri());
  return std::make_unique<RecordingBus>(PrivateTag{}, std::move(inner), std::move(file), std::move(name));
}

RecordingBus::RecordingBus(PrivateTag, std::unique_ptr<Bus> inner, UniqueFd file, std::string interface)
    : inner_(std::move(inner)), file_(std::move(file)), interface_(std::move(interface)) {}

Result<std::optional<CanFrame>> RecordingBus::receive() {
  auto r = inner_->receive();
  if (r && r->has_value()) record(**r);
  return r;
}

Result<void> RecordingBus::send(const CanFrame& frame) {
  auto r = inner_->send(frame);
  if (r) {
    CanFrame sent = frame;
    sent.timestamp_ns = detail::realtime_ns();
    record(sent);
  }
  return r;
}

BusStats RecordingBus::stats() const {
  BusStats s = inner_->stats();
  s.record_errors += record_errors_;
  return s;
}

void RecordingBus::record(const CanFrame& frame) {
  const std::string line = format_log_line(frame, interface_);
  // O_APPEND writes of a line this short are whole or fail; a partial one counts as an error.
  for (;;) {
    const ssize_t n = ::write(file_.get(), line.data(), line.size());
    if (n == static_cast<ssize_t>(line.size())) return;
    if (n < 0 && errno == EINTR) continue;
    ++record_errors_;
    return;
  }
}

}  // namespace lb::can
