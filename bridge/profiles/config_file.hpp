#pragma once
// Reading a configuration file (line, profile) whole, bounded: only a regular file is read (a
// device such as /dev/zero, a FIFO or a directory could be endless or block), and only up to a
// size no real configuration comes near.

#include <cstddef>
#include <string>
#include <string_view>

#include "base/result.hpp"

namespace lb::profiles {

// A line of 64 buses of 127 devices with their PDO overrides stays well below this.
inline constexpr std::size_t kMaxConfigFileBytes = 4 * 1024 * 1024;

// what: "line configuration", "profile file", for the error message.
Result<std::string> read_config_file(const std::string& path, std::string_view what,
                                     std::size_t max_bytes = kMaxConfigFileBytes);

}  // namespace lb::profiles
