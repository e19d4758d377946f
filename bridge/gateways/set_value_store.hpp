#pragma once
// The set values in force of a line's devices, kept across restarts of the bridge: a restart must
// not send a running line zeros (a saw switching its program off, pullers to speed 0). What is
// kept is what the bridge last sent: the payload of each RPDO with its mapping, so a payload is
// never restored into a PDO whose mapping changed. One file per line,
// <state_dir>/<line>.set_values, text (one RPDO a line), written atomically (temporary file,
// fsync, rename) by a thread of its own at most every kWriteInterval, so no bus loop ever waits
// for the disk; a crash loses at most the last interval's changes.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "base/result.hpp"

namespace lb::gateways {

class SetValueStore {
 public:
  static constexpr std::chrono::milliseconds kWriteInterval{200};
  static constexpr std::size_t kMaxFileBytes = 1 << 20;

  struct Entry {
    std::vector<std::uint32_t> mapping;  // index(16) sub(8) bits(8) per entry, as sent
    std::vector<std::uint8_t> payload;
  };

  // Reads the file when `restore` (a missing file is an empty store); fails when the directory
  // cannot be written or the file cannot be read. Lines it cannot parse are skipped with a warning.
  static Result<std::unique_ptr<SetValueStore>> open(const std::string& state_dir, const std::string& line, bool restore);
  SetValueStore(std::string path, std::map<std::string, Entry> restored);
  ~SetValueStore();  // writes what is pending, then stops
  SetValueStore(const SetValueStore&) = delete;
  SetValueStore& operator=(const SetValueStore&) = delete;

  const std::string& path() const { return path_; }
  // What the file held for a device's PDO at start-up.
  std::optional<Entry> restored(const std::string& device, const std::string& pdo) const;
  // Any thread, never blocks on the disk: the newest values of a PDO, written soon.
  void save(const std::string& device, const std::string& pdo, Entry entry);
  std::uint64_t write_failures() const;

 private:
  static std::string key(const std::string& device, const std::string& pdo) { return device + " " + pdo; }
  void run();
  bool write_file(const std::map<std::string, Entry>& values);

  std::string path_;
  const std::map<std::string, Entry> restored_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, Entry> current_;  // guarded by mutex_
  bool dirty_ = false;                    // guarded by mutex_
  bool stopping_ = false;                 // guarded by mutex_
  std::uint64_t write_failures_ = 0;      // guarded by mutex_
  std::thread thread_;
};

}  // namespace lb::gateways
