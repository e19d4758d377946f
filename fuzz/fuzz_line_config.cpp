// The YAML line configuration loader (profiles/line_config, against the built-in profiles): any
// text loads or is refused with a message, never a crash, an uncaught exception or a hang.
#include <cstdint>
#include <string>

#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/text_input.hpp"

using namespace lb::profiles;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const ProfileRegistry registry = ProfileRegistry::builtin();
  const std::string text = lb::fuzz::as_text(data, size);
  const auto config = parse_line_config(text, "fuzz.yaml", registry);
  (void)lb::fuzz::accepted(config);
  return 0;
}
