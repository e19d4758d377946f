// The EDS/DCF reader (profiles/eds, CiA 306): any text is a device description or is refused with
// a message, never a crash, an uncaught exception or a hang; what it accepts can be looked up.
#include <cstdint>
#include <string>

#include "profiles/eds.hpp"
#include "support/text_input.hpp"

using namespace lb::profiles;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lb::fuzz::as_text(data, size);
  const auto eds = parse_eds(text, "fuzz.eds");
  if (!lb::fuzz::accepted(eds)) return 0;
  for (const auto& e : eds->entries) {
    if (eds->find(e.index, e.sub) == nullptr) __builtin_trap();
    (void)eds_number(e.default_value, eds->node_id);
  }
  return 0;
}
