#pragma once
// One object definition as profile files and a line file's device `objects:` write it: index,
// sub, name, type, access (default ro), unit, scale, eng_unit, min, max, mandatory, values,
// special_values. The caller checks which keys its context allows. Throws ConfigError (start-up).

#include <string>

#include "profiles/profile.hpp"
#include "profiles/yaml_source.hpp"

namespace lb::profiles {

ObjectDef parse_object_fields(const YamlSource& src, const YAML::Node& o, const std::string& what);

}  // namespace lb::profiles
