#pragma once
// The set values in force of a line's devices, kept across restarts of the bridge: a restart must
// not send a running line zeros (a saw switching its program off, pullers to speed 0). What is
// kept is what the bridge last sent: the payload of each RPDO with its mapping, keyed by what the
// device *is* (bus, node-ID, profile) and stamped with the identity its boot read (1018h) and the
// time the bridge last held it in force. So a renamed device keeps its values, another device at
// that node-ID gets none, and a file from before a long stop restores nothing
// (StartupPolicy::set_values_max_age). Whether and what is restored is DeviceOutput's decision.
//
// One file per line, <state_dir>/<line>.set_values, text, written atomically (a fresh temporary
// file opened without following links, fsync, rename, fsync of the directory) by a thread of its
// own at most every kWriteInterval and at least every kRefreshInterval (the held-in-force stamps),
// so no bus loop ever waits for the disk; a crash loses at most the last interval's changes.
// A store that cannot be used is reported (problem(): diagnostics, --check), never silent.
//
// Beside them, the holds on the line's devices (gateways/persistence/kept_holds.hpp:
// <state_dir>/<line>.holds), written the same atomic way by the same thread whenever one is set,
// changed or released. A holds file that cannot be read restores no hold (holds_problem(): the
// line runs, diagnostics say why) and is replaced at the first change.

#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "base/result.hpp"
#include "gateways/persistence/kept_holds.hpp"

namespace lb::gateways {

class SetValueStore {
 public:
  static constexpr std::chrono::milliseconds kWriteInterval{200};
  static constexpr std::chrono::seconds kRefreshInterval{60};
  static constexpr std::size_t kMaxFileBytes = 1 << 20;
  static constexpr int kFormat = 2;

  // What the device is: the file's key. pdo: rpdo1, ...
  struct Key {
    std::string bus;
    unsigned node_id = 0;
    std::string profile;  // id@version
    std::string pdo;
    // NOLINTNEXTLINE(modernize-use-nullptr): clang-tidy 14 misreads a defaulted <=>
    auto operator<=>(const Key&) const = default;
  };
  struct Entry {
    std::array<std::uint32_t, 4> identity{};  // 1018h sub 1..4 as the device's boot read them
    std::int64_t held_at_s = 0;               // Unix time the bridge last held it in force
    std::vector<std::uint32_t> mapping;       // index(16) sub(8) bits(8) per entry, as sent
    std::vector<std::uint8_t> payload;
  };

  // Checks that <state_dir> is a directory the bridge can write, then reads the file when
  // `restore` (a missing file is an empty store). Refused: a directory that cannot be used, a
  // file that is a link, not a regular file, over kMaxFileBytes or unreadable. Lines it cannot
  // parse are skipped and counted (a few logged, then one summary). The holds file is read
  // whatever `restore` says (a stop is no value that could start a machine); one that cannot be
  // used restores no hold and says why (holds_problem), it does not refuse the store.
  static Result<std::unique_ptr<SetValueStore>> open(const std::string& state_dir, const std::string& line,
                                                     bool restore);
  SetValueStore(std::string path, std::map<Key, Entry> restored, std::string holds_path = {},
                std::map<KeptHold::Key, KeptHold> restored_holds = {}, std::string holds_problem = {});
  ~SetValueStore();  // writes what is pending, then stops
  SetValueStore(const SetValueStore&) = delete;
  SetValueStore& operator=(const SetValueStore&) = delete;

  const std::string& path() const { return path_; }
  // What the file held for a device's PDO at start-up.
  std::optional<Entry> restored(const Key& key) const;
  // Any thread, never blocks on the disk: the newest values of a PDO, written soon; from now on
  // its held-in-force stamp follows the clock.
  void save(const Key& key, Entry entry);
  std::uint64_t write_failures() const;
  // Empty while the last write succeeded; else why the file is not being kept up to date.
  std::string problem() const;

  const std::string& holds_path() const { return holds_path_; }
  // The holds the file kept at start-up.
  const std::map<KeptHold::Key, KeptHold>& restored_holds() const { return restored_holds_; }
  // Why the holds file restored nothing or not all of it (empty: it restored all it held, or
  // there was none).
  const std::string& holds_problem() const { return holds_problem_; }
  // Any thread, never blocks on the disk: a device's hold set or changed, or released (nullopt);
  // written soon.
  void save_hold(const KeptHold::Key& key, std::optional<KeptHold> hold);

 private:
  void run();
  bool write_file(const std::string& path, const std::string& text, std::string& why);

  std::string path_;
  const std::map<Key, Entry> restored_;
  const std::string holds_path_;
  const std::map<KeptHold::Key, KeptHold> restored_holds_;
  const std::string holds_problem_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::map<Key, Entry> current_;             // guarded by mutex_
  std::set<Key> live_;                       // guarded by mutex_: saved in this run, stamped at every write
  bool dirty_ = false;                       // guarded by mutex_
  bool stopping_ = false;                    // guarded by mutex_
  std::map<KeptHold::Key, KeptHold> holds_;  // guarded by mutex_
  bool holds_dirty_ = false;                 // guarded by mutex_
  std::uint64_t write_failures_ = 0;         // guarded by mutex_
  std::string problem_;                      // guarded by mutex_: of the set-value file
  std::string holds_write_problem_;          // guarded by mutex_: of the holds file
  std::chrono::steady_clock::time_point
      failure_logged_{};  // the writer thread's: a failing disk is logged once a minute
  std::thread thread_;
};

}  // namespace lb::gateways
