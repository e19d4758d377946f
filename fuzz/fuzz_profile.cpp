// The YAML device profile loader (profiles/profile_registry): any text is a profile or is refused
// with a message, never a crash, an uncaught exception or a hang; a profile it accepts is usable
// (its PDOs resolve for a node).
#include <cstdint>
#include <string>

#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/text_input.hpp"

using namespace lb::profiles;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lb::fuzz::as_text(data, size);
  const auto profile = parse_profile(text, "fuzz.yaml");
  if (!lb::fuzz::accepted(profile)) return 0;
  for (const auto& pdo : default_pdos(*profile, 127)) {
    if (pdo.can_id > 0x7FF && !pdo.extended) __builtin_trap();
  }
  return 0;
}
