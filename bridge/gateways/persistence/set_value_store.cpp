#include "gateways/persistence/set_value_store.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <sstream>

#include "can/unique_fd.hpp"
#include "profiles/config_file.hpp"

namespace lb::gateways {

namespace {

constexpr unsigned kLoggedBadLines = 3;

std::string hex_bytes(const std::vector<std::uint8_t>& b) {
  std::string s;
  for (auto v : b) s += fmt::format("{:02X}", v);
  return s.empty() ? "-" : s;
}

template <class T>
std::optional<T> parse_hex(std::string_view s) {
  T v{};
  if (s.empty()) return std::nullopt;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v, 16);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<std::vector<std::uint8_t>> parse_bytes(const std::string& s) {
  std::vector<std::uint8_t> out;
  if (s == "-") return out;
  if (s.size() % 2 != 0 || s.size() > 16) return std::nullopt;
  for (std::size_t i = 0; i < s.size(); i += 2) {
    const auto v = parse_hex<std::uint8_t>(std::string_view(s).substr(i, 2));
    if (!v) return std::nullopt;
    out.push_back(*v);
  }
  return out;
}

std::optional<std::vector<std::uint32_t>> parse_words(const std::string& s, char sep, std::size_t max) {
  std::vector<std::uint32_t> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, sep)) {
    if (item.size() != 8) return std::nullopt;
    const auto v = parse_hex<std::uint32_t>(item);
    if (!v) return std::nullopt;
    out.push_back(*v);
  }
  if (out.empty() || out.size() > max) return std::nullopt;
  return out;
}

std::string errno_text(int e) { return std::strerror(e); }

std::int64_t unix_now() {
  return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// One line: bus node profile identity held_at pdo mapping payload.
std::optional<std::pair<SetValueStore::Key, SetValueStore::Entry>> parse_line(const std::string& text) {
  std::stringstream fields(text);
  std::string bus, node, profile, identity, held, pdo, mapping, payload, extra;
  fields >> bus >> node >> profile >> identity >> held >> pdo >> mapping >> payload;
  if (payload.empty() || (fields >> extra)) return std::nullopt;
  SetValueStore::Key key{bus, 0, profile, pdo};
  const auto [nend, nec] = std::from_chars(node.data(), node.data() + node.size(), key.node_id);
  if (nec != std::errc() || nend != node.data() + node.size() || key.node_id < 1 || key.node_id > 127)
    return std::nullopt;
  SetValueStore::Entry e;
  const auto [hend, hec] = std::from_chars(held.data(), held.data() + held.size(), e.held_at_s);
  if (hec != std::errc() || hend != held.data() + held.size()) return std::nullopt;
  const auto id = parse_words(identity, ':', 4);
  auto m = parse_words(mapping, ',', 64);
  auto p = parse_bytes(payload);
  if (!id || id->size() != 4 || !m || !p) return std::nullopt;
  std::copy(id->begin(), id->end(), e.identity.begin());
  e.mapping = std::move(*m);
  e.payload = std::move(*p);
  return std::pair{std::move(key), std::move(e)};
}

Result<std::map<SetValueStore::Key, SetValueStore::Entry>> read_file(const std::string& path) {
  // A link planted in the state directory is refused, never followed; the rest (a FIFO, a
  // directory, a file over the bound) is refused as any configuration file is.
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return std::map<SetValueStore::Key, SetValueStore::Entry>{};
    return make_error(path + ": " + errno_text(errno));
  }
  if (S_ISLNK(st.st_mode))
    return make_error(path + ": a symbolic link; the set values are kept only in a regular file");
  auto text = profiles::read_config_file(path, "set-value file", SetValueStore::kMaxFileBytes);
  if (!text) return text.error();

  std::map<SetValueStore::Key, SetValueStore::Entry> restored;
  std::stringstream in(*text);
  std::string line;
  bool format_seen = false;
  unsigned bad = 0;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.empty() || line[0] == '#') continue;
    if (line.rfind("format ", 0) == 0) {
      if (line != fmt::format("format {}", SetValueStore::kFormat)) {
        spdlog::warn("{}:{}: '{}': not this bridge's set-value format ({}): nothing restored", path, n, line,
                     SetValueStore::kFormat);
        return std::map<SetValueStore::Key, SetValueStore::Entry>{};
      }
      format_seen = true;
      continue;
    }
    if (!format_seen) {
      // Format 1 (keyed by device name, without identity or age) or not ours: nothing of it is
      // trusted to go back into a device.
      spdlog::warn("{}:{}: no 'format {}' line before the values (an older bridge's file?): nothing restored", path, n,
                   SetValueStore::kFormat);
      return std::map<SetValueStore::Key, SetValueStore::Entry>{};
    }
    auto parsed = parse_line(line);
    if (!parsed) {
      if (++bad <= kLoggedBadLines) spdlog::warn("{}:{}: not a set-value line, skipped", path, n);
      continue;
    }
    restored[parsed->first] = std::move(parsed->second);
  }
  if (bad > kLoggedBadLines) spdlog::warn("{}: {} lines in all were not set-value lines and were skipped", path, bad);
  return restored;
}

std::string values_text(const std::map<SetValueStore::Key, SetValueStore::Entry>& values) {
  std::string text =
      fmt::format("# linebridge: the set values in force, one RPDO a line:\n"
                  "# bus node-ID profile identity(1018h sub 1:2:3:4) held-in-force(Unix s) pdo mapping payload(hex)\n"
                  "format {}\n",
                  SetValueStore::kFormat);
  for (const auto& [k, e] : values) {
    std::string mapping;
    for (auto m : e.mapping) mapping += fmt::format("{}{:08X}", mapping.empty() ? "" : ",", m);
    text += fmt::format("{} {} {} {:08X}:{:08X}:{:08X}:{:08X} {} {} {} {}\n", k.bus, k.node_id, k.profile,
                        e.identity[0], e.identity[1], e.identity[2], e.identity[3], e.held_at_s, k.pdo, mapping,
                        hex_bytes(e.payload));
  }
  return text;
}

// The holds file: never a reason to refuse the store; what cannot be read restores no hold and
// says why (the line runs; the file is replaced at the first change).
std::map<KeptHold::Key, KeptHold> read_holds(const std::string& path, std::string& why) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno != ENOENT) why = path + ": " + errno_text(errno) + ": no hold restored";
    return {};
  }
  if (S_ISLNK(st.st_mode)) {
    why = path + ": a symbolic link (holds are kept only in a regular file): no hold restored";
  } else if (auto text = profiles::read_config_file(path, "hold file", SetValueStore::kMaxFileBytes); !text) {
    why = text.error().message + ": no hold restored";
  } else {
    return parse_holds(*text, path, why);
  }
  spdlog::error("{}; devices held before the restart are booted and started as if never held", why);
  return {};
}

}  // namespace

Result<std::unique_ptr<SetValueStore>> SetValueStore::open(const std::string& state_dir, const std::string& line,
                                                           bool restore) {
  const std::string path = state_dir + "/" + line + ".set_values";
  struct stat st {};
  if (::stat(state_dir.c_str(), &st) != 0) {
    return make_error("state_dir " + state_dir + ": " + errno_text(errno) + " (set values in force are kept there)");
  }
  if (!S_ISDIR(st.st_mode))
    return make_error("state_dir " + state_dir + ": not a directory (set values in force are kept there)");
  if (::access(state_dir.c_str(), W_OK | X_OK) != 0) {
    return make_error("state_dir " + state_dir + ": " + errno_text(errno) + " (set values in force are kept there)");
  }
  std::map<Key, Entry> restored;
  if (restore) {
    auto r = read_file(path);
    if (!r) return r.error();
    restored = std::move(*r);
  } else {
    // The file must still be ours to replace: refuse a link or a non-file now, not at the first write.
    if (::lstat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) return make_error(path + ": not a regular file");
  }
  const std::string holds_path = state_dir + "/" + line + ".holds";
  std::string holds_problem;
  auto holds = read_holds(holds_path, holds_problem);
  if (!holds.empty()) spdlog::info("{}: {} hold(s) kept from before the restart", holds_path, holds.size());
  return std::make_unique<SetValueStore>(path, std::move(restored), holds_path, std::move(holds),
                                         std::move(holds_problem));
}

SetValueStore::SetValueStore(std::string path, std::map<Key, Entry> restored, std::string holds_path,
                             std::map<KeptHold::Key, KeptHold> restored_holds, std::string holds_problem)
    : path_(std::move(path)),
      restored_(std::move(restored)),
      holds_path_(holds_path.empty() ? path_.substr(0, path_.rfind('.')) + ".holds" : std::move(holds_path)),
      restored_holds_(std::move(restored_holds)),
      holds_problem_(std::move(holds_problem)),
      current_(restored_),
      holds_(restored_holds_) {
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

std::optional<SetValueStore::Entry> SetValueStore::restored(const Key& key) const {
  const auto it = restored_.find(key);
  if (it == restored_.end()) return std::nullopt;
  return it->second;
}

void SetValueStore::save(const Key& key, Entry entry) {
  {
    std::lock_guard lock(mutex_);
    const bool was_live = !live_.insert(key).second;
    auto& slot = current_[key];
    if (was_live && slot.mapping == entry.mapping && slot.payload == entry.payload && slot.identity == entry.identity)
      return;
    slot = std::move(entry);
    dirty_ = true;
  }
  cv_.notify_all();
}

void SetValueStore::save_hold(const KeptHold::Key& key, std::optional<KeptHold> hold) {
  {
    std::lock_guard lock(mutex_);
    const auto it = holds_.find(key);
    if (!hold) {
      if (it == holds_.end()) return;
      holds_.erase(it);
    } else {
      if (it != holds_.end() && it->second == *hold) return;
      holds_[key] = std::move(*hold);
    }
    holds_dirty_ = true;
  }
  cv_.notify_all();
}

std::uint64_t SetValueStore::write_failures() const {
  std::lock_guard lock(mutex_);
  return write_failures_;
}

std::string SetValueStore::problem() const {
  std::lock_guard lock(mutex_);
  if (holds_write_problem_.empty()) return problem_;
  return problem_.empty() ? holds_write_problem_ : problem_ + "; " + holds_write_problem_;
}

void SetValueStore::run() {
  std::unique_lock lock(mutex_);
  auto refresh_due = std::chrono::steady_clock::now() + kRefreshInterval;
  for (;;) {
    cv_.wait_until(lock, refresh_due, [this] { return dirty_ || holds_dirty_ || stopping_; });
    const auto now = std::chrono::steady_clock::now();
    const bool refresh = now >= refresh_due;
    if (refresh) refresh_due = now + kRefreshInterval;
    // A store nothing was saved to in this run (--check, a line whose devices never started)
    // leaves the file as it found it.
    if (dirty_ || (!live_.empty() && (stopping_ || refresh))) {
      dirty_ = false;
      // What this run holds in force is stamped now; the rest keeps the time it was last held.
      const auto stamp = unix_now();
      for (const auto& k : live_) current_[k].held_at_s = stamp;
      const auto values = current_;
      lock.unlock();
      std::string why;
      const bool ok = write_file(path_, values_text(values), why);
      lock.lock();
      if (ok) {
        if (!problem_.empty()) spdlog::info("{}: the set values in force are kept again", path_);
        problem_.clear();
      } else {
        ++write_failures_;
        problem_ = why;
        dirty_ = !stopping_;  // tried again at the next interval
      }
    }
    // Holds change seldom (an operator's stop, the line's reaction): written when they do.
    if (holds_dirty_) {
      holds_dirty_ = false;
      const auto holds = holds_;
      lock.unlock();
      std::string why;
      const bool ok = write_file(holds_path_, holds_text(holds), why);
      lock.lock();
      if (ok) {
        if (!holds_write_problem_.empty()) spdlog::info("{}: the holds are kept again", holds_path_);
        holds_write_problem_.clear();
      } else {
        ++write_failures_;
        holds_write_problem_ = why;
        holds_dirty_ = !stopping_;
      }
    }
    // What changed while the last write ran (the lock is released for it) is written before the end.
    if (stopping_) {
      if (!dirty_ && !holds_dirty_) return;
      continue;
    }
    // Coalesce: set values change in bursts (a ramp, a pulse); one write per interval is enough.
    cv_.wait_for(lock, kWriteInterval, [this] { return stopping_; });
  }
}

bool SetValueStore::write_file(const std::string& path, const std::string& text, std::string& why) {
  const std::string tmp = path + ".tmp";
  const auto fail = [&](const char* what, const std::string& file) {
    why = fmt::format("{} {}: {}", what, file, errno_text(errno));
    static_cast<void>(::unlink(tmp.c_str()));
    const auto now = std::chrono::steady_clock::now();
    if (failure_logged_ == std::chrono::steady_clock::time_point{} ||
        now - failure_logged_ >= std::chrono::minutes(1)) {
      failure_logged_ = now;
      spdlog::error("{}: {} could not be kept: {} (tried again; logged once a minute)", path,
                    path == holds_path_ ? "the holds" : "the set values in force", why);
    }
    return false;
  };
  // Whatever stands at the temporary name (a stale file, a planted link) goes; the new file is
  // created afresh, never through a link.
  if (::unlink(tmp.c_str()) != 0 && errno != ENOENT) return fail("remove", tmp);
  can::UniqueFd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0640));
  if (!fd) return fail("create", tmp);
  for (std::size_t done = 0; done < text.size();) {
    const ssize_t n = ::write(fd.get(), text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      if (n == 0) errno = ENOSPC;
      return fail("write", tmp);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd.get()) != 0) return fail("fsync", tmp);
  fd = can::UniqueFd();
  if (::rename(tmp.c_str(), path.c_str()) != 0) return fail("rename to", path);
  // The rename is durable only once the directory is: without this a power cut can lose the file.
  const auto slash = path.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : path.substr(0, slash);
  can::UniqueFd dfd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (!dfd || ::fsync(dfd.get()) != 0) return fail("fsync the directory", dir);
  failure_logged_ = {};
  return true;
}

}  // namespace lb::gateways
