#include "profiles/yaml_source.hpp"

#include <algorithm>

#include "profiles/config_file.hpp"
#include "profiles/yaml_structure.hpp"

namespace lb::profiles {

std::string YamlSource::where(const YAML::Node& node) const {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null()) return name_;
  return name_ + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

void YamlSource::fail(const YAML::Node& node, std::string_view what) const {
  throw ConfigError(where(node) + ": " + std::string(what));
}

YAML::Node YamlSource::parse(const std::string& text) const {
  // The same bound as a file has, for text from anywhere else.
  if (text.size() > kMaxConfigFileBytes) {
    throw ConfigError(name_ + ": larger than " + std::to_string(kMaxConfigFileBytes) + " bytes (" +
                      std::to_string(text.size()) + ")");
  }
  check_yaml_structure(text, name_);
  try {
    return YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw ConfigError(name_ + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1) +
                      ": YAML syntax error: " + e.msg);
  }
}

void YamlSource::expect_map(const YAML::Node& node, std::string_view what) const {
  if (!node.IsMap()) fail(node, std::string(what) + " must be a mapping (key: value)");
}

void YamlSource::expect_sequence(const YAML::Node& node, std::string_view what) const {
  if (!node.IsSequence()) fail(node, std::string(what) + " must be a list");
}

void YamlSource::check_keys(const YAML::Node& map, std::string_view what,
                            std::initializer_list<std::string_view> allowed) const {
  expect_map(map, what);
  for (const auto& kv : map) {
    const auto key = kv.first.as<std::string>();
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    std::string list;
    for (auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    fail(kv.first, "unknown key '" + key + "' in " + std::string(what) + " (allowed: " + list + ")");
  }
}

std::string YamlSource::scalar_text(const YAML::Node& node) {
  if (node.IsScalar()) return node.Scalar();
  if (node.IsSequence()) return "<list>";
  if (node.IsMap()) return "<mapping>";
  return "<null>";
}

}  // namespace lb::profiles
