#include "gateways/set_value_store.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace lb::gateways {

namespace {

std::string hex_bytes(const std::vector<std::uint8_t>& b) {
  std::string s;
  for (auto v : b) s += fmt::format("{:02X}", v);
  return s.empty() ? "-" : s;
}

std::optional<std::vector<std::uint8_t>> parse_bytes(const std::string& s) {
  std::vector<std::uint8_t> out;
  if (s == "-") return out;
  if (s.size() % 2 != 0 || s.size() > 16) return std::nullopt;
  for (std::size_t i = 0; i < s.size(); i += 2) {
    unsigned v = 0;
    if (std::sscanf(s.c_str() + i, "%2X", &v) != 1) return std::nullopt;
    out.push_back(static_cast<std::uint8_t>(v));
  }
  return out;
}

std::optional<std::vector<std::uint32_t>> parse_mapping(const std::string& s) {
  std::vector<std::uint32_t> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (item.size() != 8) return std::nullopt;
    char* end = nullptr;
    const auto v = std::strtoul(item.c_str(), &end, 16);
    if (end != item.c_str() + item.size()) return std::nullopt;
    out.push_back(static_cast<std::uint32_t>(v));
  }
  if (out.empty() || out.size() > 64) return std::nullopt;
  return out;
}

std::string errno_text() { return std::strerror(errno); }

}  // namespace

Result<std::unique_ptr<SetValueStore>> SetValueStore::open(const std::string& state_dir, const std::string& line,
                                                           bool restore) {
  const std::string path = state_dir + "/" + line + ".set_values";
  if (::access(state_dir.c_str(), W_OK | X_OK) != 0) {
    return make_error("state_dir " + state_dir + ": " + errno_text() + " (set values in force are kept there)");
  }
  std::map<std::string, Entry> restored;
  if (restore) {
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
      if (!S_ISREG(st.st_mode)) return make_error(path + ": not a regular file");
      if (static_cast<std::size_t>(st.st_size) > kMaxFileBytes) return make_error(path + ": larger than 1 MiB, not a set-value file");
      std::ifstream in(path);
      if (!in) return make_error(path + ": cannot be read");
      std::string text;
      for (int n = 1; std::getline(in, text); ++n) {
        if (text.empty() || text[0] == '#') continue;
        std::stringstream fields(text);
        std::string device, pdo, mapping, payload, extra;
        fields >> device >> pdo >> mapping >> payload;
        auto m = parse_mapping(mapping);
        auto p = parse_bytes(payload);
        if (device.empty() || pdo.empty() || !m || !p || (fields >> extra)) {
          spdlog::warn("{}:{}: not a set-value line, skipped", path, n);
          continue;
        }
        restored[key(device, pdo)] = Entry{std::move(*m), std::move(*p)};
      }
    } else if (errno != ENOENT) {
      return make_error(path + ": " + errno_text());
    }
  }
  return std::make_unique<SetValueStore>(path, std::move(restored));
}

SetValueStore::SetValueStore(std::string path, std::map<std::string, Entry> restored)
    : path_(std::move(path)), restored_(std::move(restored)), current_(restored_) {
  thread_ = std::thread([this] { run(); });
}

SetValueStore::~SetValueStore() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

std::optional<SetValueStore::Entry> SetValueStore::restored(const std::string& device, const std::string& pdo) const {
  const auto it = restored_.find(key(device, pdo));
  if (it == restored_.end()) return std::nullopt;
  return it->second;
}

void SetValueStore::save(const std::string& device, const std::string& pdo, Entry entry) {
  {
    std::lock_guard lock(mutex_);
    auto& slot = current_[key(device, pdo)];
    if (slot.mapping == entry.mapping && slot.payload == entry.payload) return;
    slot = std::move(entry);
    dirty_ = true;
  }
  cv_.notify_all();
}

std::uint64_t SetValueStore::write_failures() const {
  std::lock_guard lock(mutex_);
  return write_failures_;
}

void SetValueStore::run() {
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait(lock, [this] { return dirty_ || stopping_; });
    if (dirty_) {
      dirty_ = false;
      const auto values = current_;
      lock.unlock();
      const bool ok = write_file(values);
      lock.lock();
      if (!ok) {
        ++write_failures_;
        dirty_ = true;  // tried again at the next interval
      }
    }
    if (stopping_ && !dirty_) return;
    if (stopping_) continue;  // one last try, without waiting
    // Coalesce: set values change in bursts (a ramp, a pulse); one write per interval is enough.
    cv_.wait_for(lock, kWriteInterval, [this] { return stopping_; });
  }
}

bool SetValueStore::write_file(const std::map<std::string, Entry>& values) {
  std::string text = "# linebridge: the set values in force, one RPDO a line: device pdo mapping payload (hex)\n";
  for (const auto& [k, e] : values) {
    std::string mapping;
    for (auto m : e.mapping) mapping += fmt::format("{}{:08X}", mapping.empty() ? "" : ",", m);
    text += fmt::format("{} {} {}\n", k, mapping, hex_bytes(e.payload));
  }
  const std::string tmp = path_ + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bool ok = fd >= 0;
  for (std::size_t done = 0; ok && done < text.size();) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    ok = n > 0;
    if (ok) done += static_cast<std::size_t>(n);
  }
  ok = ok && ::fsync(fd) == 0;
  if (fd >= 0) ::close(fd);
  ok = ok && ::rename(tmp.c_str(), path_.c_str()) == 0;
  if (!ok) {
    static_cast<void>(::unlink(tmp.c_str()));
    spdlog::error("{}: the set values in force could not be kept: {}", path_, errno_text());
  }
  return ok;
}

}  // namespace lb::gateways
