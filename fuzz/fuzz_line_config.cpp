// The YAML line configuration loader (profiles/line_config, against the built-in profiles): any
// text loads or is refused with a message, never a crash, an uncaught exception or a hang.
#include <cstdint>
#include <string>

#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"

using namespace lb::profiles;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const ProfileRegistry registry = ProfileRegistry::builtin();
  const std::string text(reinterpret_cast<const char*>(data), size);
  const auto config = parse_line_config(text, "fuzz.yaml", registry);
  if (!config && config.error().message.empty()) __builtin_trap();
  return 0;
}
