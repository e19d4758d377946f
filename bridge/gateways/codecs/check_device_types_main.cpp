// lb-check-device-types: run by the build (bridge/gateways/CMakeLists.txt), fails it when the
// device-type registry (profiles/device_types.hpp), the built-in profiles (config/profiles/) and
// the word bindings generated from the IDL (msgs/word_bindings.hpp) disagree
// (gateways/codecs/device_type_check.hpp says what must agree). Prints every disagreement, one a
// line, then exits 1.
#include <cstdio>

#include "gateways/codecs/device_type_check.hpp"

int main() {
  const auto findings = lb::gateways::check_device_types(lb::profiles::ProfileRegistry::builtin(),
                                                         lb::profiles::device_types);
  for (const auto& f : findings) std::fprintf(stderr, "device types: %s\n", f.c_str());
  return findings.empty() ? 0 : 1;
}
