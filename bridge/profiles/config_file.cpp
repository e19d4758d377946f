#include "profiles/config_file.hpp"

#include "base/bounded_file.hpp"

namespace lb::profiles {

Result<std::string> read_config_file(const std::string& path, std::string_view what, std::size_t max_bytes) {
  return read_bounded_file(path, what, max_bytes);
}

}  // namespace lb::profiles
