#pragma once
// What the unit tests of a secured line's files share: a fresh directory of the test's own (named
// after it and the process, so runs never meet), a PKI for a line, and the line file's head (line name, DDS domain
// on localhost only, the security section) before the test's own buses and devices.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "support/scratch_files.hpp"
#include "support/test_pki.hpp"

namespace lb::test {

// <TempDir>/<kind>_<test name>-<pid>, empty.
inline std::string fresh_test_dir(const std::string& kind) {
  return fresh_dir(kind + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
}

// The PKI launch_scripts/pki.sh makes in dir/pki for a line (its file, plain_yaml, unsecured).
inline std::unique_ptr<TestPki> pki_for(const std::string& dir, const std::string& plain_yaml) {
  std::ofstream(dir + "/plain.yaml") << plain_yaml;
  return std::make_unique<TestPki>(dir + "/plain.yaml", dir + "/pki");
}

inline std::string secured_line_yaml(const std::string& line, std::uint32_t domain, const std::string& security,
                                     const std::string& buses_and_devices) {
  return "line: " + line + "\ndds:\n  domain: " + std::to_string(domain) + "\n  localhost_only: true\n" + security +
         buses_and_devices;
}

}  // namespace lb::test
