#include "app/restart_pacing.hpp"

#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "app/run_until_signal.hpp"

namespace lb::app {

std::chrono::milliseconds RestartPacer::next_pause(Clock::time_point now) {
  if (!starts_.empty() && now - starts_.back() >= pacing_.settled) step_ = 0;
  forget_before(now - pacing_.window);
  if (step_ == 0 && starts_.size() < pacing_.free_starts) return std::chrono::milliseconds::zero();
  ++step_;
  auto pause = pacing_.first_pause;
  for (unsigned i = 1; i < step_ && pause < pacing_.longest_pause; ++i) pause *= 2;
  return std::min(pause, pacing_.longest_pause);
}

void RestartPacer::started(Clock::time_point now) {
  starts_.push_back(now);
  forget_before(now - pacing_.window);
}

std::size_t RestartPacer::starts_within(Clock::time_point now) const {
  return static_cast<std::size_t>(
      std::count_if(starts_.begin(), starts_.end(), [&](Clock::time_point t) { return t > now - pacing_.window; }));
}

void RestartPacer::forget_before(Clock::time_point t) {
  // The newest start is kept whatever its age: it tells whether the last process settled.
  while (starts_.size() > 1 && starts_.front() <= t) starts_.pop_front();
}

std::string RestartPacer::record() const {
  std::ostringstream out;
  out << "step " << step_ << "\n";
  for (const auto t : starts_) out << "start " << t.time_since_epoch().count() << "\n";
  return out.str();
}

RestartPacer RestartPacer::from_record(const std::string& text, RestartPacing pacing) {
  RestartPacer pacer(pacing);
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string key;
    long long value = 0;
    if (!(fields >> key >> value)) continue;
    if (key == "step" && value >= 0 && value < 64) pacer.step_ = static_cast<unsigned>(value);
    if (key == "start" && value > 0) {
      const Clock::time_point t{Clock::duration(value)};
      // A time ahead of this clock is not of this boot: the record is stale.
      if (t <= Clock::now() && (pacer.starts_.empty() || t >= pacer.starts_.back())) pacer.starts_.push_back(t);
    }
  }
  return pacer;
}

bool pace_start(const std::string& path) {
  std::string text;
  {
    std::ifstream in(path);
    if (in) {
      std::ostringstream s;
      s << in.rdbuf();
      text = s.str();
    }
  }
  auto pacer = RestartPacer::from_record(text);
  const auto now = RestartPacer::Clock::now();
  const auto starts = pacer.starts_within(now);
  const auto pause = pacer.next_pause(now);
  if (pause.count() > 0) {
    spdlog::warn("{} DDS process start(s) in the last {} s: this one waits {:.1f} s before it starts (a back-off "
                 "that doubles up to {} s while they keep ending; it never gives up)",
                 starts, pacer.pacing().window.count(), std::chrono::duration<double>(pause).count(),
                 std::chrono::duration_cast<std::chrono::seconds>(pacer.pacing().longest_pause).count());
    sd_notifyf(0, "STATUS=waiting %.1f s before starting (%zu starts in the last %lld s)",
               std::chrono::duration<double>(pause).count(), starts,
               static_cast<long long>(pacer.pacing().window.count()));
    const sigset_t set = stop_signals();
    const auto s = std::chrono::duration_cast<std::chrono::seconds>(pause);
    const timespec ts{static_cast<time_t>(s.count()), static_cast<long>((pause - s).count() * 1'000'000)};
    if (sigtimedwait(&set, nullptr, &ts) > 0) return false;
  }
  pacer.started(RestartPacer::Clock::now());
  // Written whole, then renamed: a process killed while writing leaves the previous record.
  const auto tmp = path + ".tmp";
  std::ofstream(tmp) << pacer.record();
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) spdlog::warn("--pace-starts {}: cannot keep the record of starts ({}); no back-off", path, ec.message());
  return true;
}

}  // namespace lb::app
