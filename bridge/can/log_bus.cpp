#include "can/log_bus.hpp"

#include <sys/timerfd.h>

#include <cerrno>
#include <filesystem>
#include <istream>

#include "can/controller_state.hpp"
#include "can/detail.hpp"

namespace lb::can {
namespace {

// Frames per wake-up in fast pace: large enough for speed, small enough that a bus loop's timers
// and posted tasks still run every few hundred microseconds.
constexpr int kFastBatch = 64;

// A candump line has under 100 characters: what a longer one holds beyond this is dropped as it
// is read, so a file without line breaks cannot fill the memory.
constexpr std::size_t kMaxLine = 1024;

bool read_line(std::istream& in, std::string& line) {
  line.clear();
  bool any = false;
  for (char c; in.get(c);) {
    any = true;
    if (c == '\n') return true;
    if (line.size() < kMaxLine) line += c;
  }
  return any;
}

}  // namespace

Result<LogBus::Spec> LogBus::parse_spec(std::string_view spec) {
  Spec out;
  const auto q = spec.find('?');
  out.path = std::string(spec.substr(0, q));
  if (out.path.empty()) return make_error("log:" + std::string(spec) + ": the file path is empty");
  if (q == std::string_view::npos) return out;
  std::string_view query = spec.substr(q + 1);
  while (!query.empty()) {
    const auto amp = query.find('&');
    const std::string_view option = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view{} : query.substr(amp + 1);
    const auto eq = option.find('=');
    const std::string_view key = option.substr(0, eq);
    const std::string_view value = eq == std::string_view::npos ? std::string_view{} : option.substr(eq + 1);
    if (key == "pace" && value == "realtime") {
      out.pace = Pace::realtime;
    } else if (key == "pace" && value == "fast") {
      out.pace = Pace::fast;
    } else if (key == "pace") {
      return make_error("log:" + std::string(spec) + ": pace must be realtime or fast, not '" + std::string(value) +
                        "'");
    } else if (key == "interface" && !value.empty()) {
      out.interface = std::string(value);
    } else {
      return make_error("log:" + std::string(spec) + ": unknown option '" + std::string(option) +
                        "' (known: pace=realtime|fast, interface=<name>)");
    }
  }
  return out;
}

Result<std::unique_ptr<LogBus>> LogBus::open(std::string_view spec_text) {
  auto spec = parse_spec(spec_text);
  if (!spec) return spec.error();
  std::string uri = "log:" + std::string(spec_text);
  // A device (/dev/zero) or a FIFO never ends and has no lines: only a recording on disk replays.
  std::error_code ec;
  if (const auto st = std::filesystem::status(spec->path, ec); !ec && !std::filesystem::is_regular_file(st)) {
    return make_error(uri + ": " + spec->path + " is not a regular file");
  }
  std::ifstream in(spec->path);
  if (!in) return make_error(uri + ": cannot open " + spec->path + ": " + detail::errno_text(errno));
  UniqueFd timer{::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC)};
  if (!timer) return make_error(uri + ": timerfd_create failed: " + detail::errno_text(errno));
  auto bus = std::make_unique<LogBus>(PrivateTag{}, std::move(uri), std::move(*spec), std::move(in), std::move(timer));
  bus->read_next();
  // Anything but a frame before the first frame: most likely not a log file at all.
  if (bus->bad_line_) return *bus->bad_line_;
  if (!bus->pending_)
    return make_error(bus->uri_ + ": the file holds no frame" +
                      (bus->spec_.interface.empty() ? "" : " of interface " + bus->spec_.interface));
  bus->first_ns_ = bus->pending_->timestamp_ns;
  bus->stats_.state = BusState::error_active;
  bus->fast_budget_ = kFastBatch;
  bus->wake_at({});  // readable at once: the first frame is due as soon as someone reads
  return bus;
}

LogBus::LogBus(PrivateTag, std::string uri, Spec spec, std::ifstream in, UniqueFd timer)
    : uri_(std::move(uri)), spec_(std::move(spec)), in_(std::move(in)), timer_(std::move(timer)) {}

void LogBus::read_next() {
  pending_.reset();
  std::string line;
  while (read_line(in_, line)) {
    ++line_no_;
    auto rec = parse_log_line(line);
    if (!rec) {
      // Reported once, by the next receive(); the replay goes on with the following lines.
      if (!bad_line_) bad_line_ = make_error(spec_.path + ":" + std::to_string(line_no_) + ": " + rec.error().message);
      continue;
    }
    if (!*rec) continue;
    if (!spec_.interface.empty() && (*rec)->interface != spec_.interface) continue;
    pending_ = (*rec)->frame;
    return;
  }
  eof_ = true;
}

// A time in the past (or the epoch) makes the timer readable at once.
void LogBus::wake_at(std::chrono::steady_clock::time_point when) {
  itimerspec spec{};
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(when.time_since_epoch()).count();
  const std::int64_t at = ns > 0 ? ns : 1;
  spec.it_value.tv_sec = static_cast<time_t>(at / 1'000'000'000);
  spec.it_value.tv_nsec = static_cast<long>(at % 1'000'000'000);
  ::timerfd_settime(timer_.get(), TFD_TIMER_ABSTIME, &spec, nullptr);
}

Result<std::optional<CanFrame>> LogBus::receive() {
  std::uint64_t expirations = 0;
  [[maybe_unused]] const auto n = ::read(timer_.get(), &expirations, sizeof expirations);  // re-armed below
  if (bad_line_) {
    Error e = std::move(*bad_line_);
    bad_line_.reset();
    wake_at({});
    return e;
  }
  if (!pending_) {
    stats_.state = BusState::down;  // the recording has ended
    return std::optional<CanFrame>{};
  }
  const auto now = std::chrono::steady_clock::now();
  if (!start_) start_ = now;

  if (spec_.pace == Pace::fast) {
    // One batch, then "nothing due" with the timer readable at once: the caller's loop comes round.
    if (fast_budget_ == 0) {
      fast_budget_ = kFastBatch;
      wake_at({});
      return std::optional<CanFrame>{};
    }
    --fast_budget_;
  } else {
    const auto due = *start_ + std::chrono::nanoseconds(pending_->timestamp_ns - first_ns_);
    if (due > now) {
      wake_at(due);
      return std::optional<CanFrame>{};
    }
  }

  const CanFrame frame = *pending_;
  if (frame.error) {
    ++stats_.error_frames;
    apply_error_frame(frame, stats_);
  } else {
    ++stats_.frames_in;
  }
  read_next();
  // Readable again at once: a caller that reads one frame per wake-up still gets them all.
  wake_at({});
  return std::optional<CanFrame>{frame};
}

Result<void> LogBus::send(const CanFrame& /*frame*/) {
  ++stats_.tx_dropped;
  return make_error("bus " + uri_ + " replays a recording: transmission refused (run it as a monitor)");
}

}  // namespace lb::can
