#pragma once
// Files a test writes and reads back under the test's temporary directory.

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace lb::test {

// An empty directory of this test process, named after `name` (left over from an earlier run of
// the same pid, as pids come round: emptied).
inline std::string fresh_dir(const std::string& name) {
  const auto dir =
      std::filesystem::path(::testing::TempDir() + "/" + name + "-" + std::to_string(::getpid())).lexically_normal();
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

// The whole file ("" when it cannot be read).
inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace lb::test
