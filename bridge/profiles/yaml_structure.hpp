#pragma once
// What YAML allows and a configuration file must not have, checked on the parser's events before
// the document is built: a key given twice in one mapping (yaml-cpp keeps one silently), a key
// that is not a plain scalar (`? [a, b]`), nesting deeper than any configuration needs, and
// aliases that expand to more nodes than a file may hold (a "billion laughs" document).

#include <cstddef>
#include <string>

namespace lb::profiles {

struct YamlLimits {
  std::size_t max_depth = 32;         // our files nest 6 deep
  std::size_t max_nodes = 2'000'000;  // after aliases are expanded
};

// Throws ConfigError naming source:line:column of the offending node; YAML syntax errors too.
void check_yaml_structure(const std::string& text, const std::string& source, const YamlLimits& limits = {});

}  // namespace lb::profiles
