#pragma once
// Strict reading of YAML configuration: every error names the file, line and column and what is
// wrong, and unknown keys are errors (a typo must never be silently ignored on a running line).

#include <yaml-cpp/yaml.h>

#include <initializer_list>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace lb::profiles {

// Thrown only while loading (start-up); the public loaders turn it into a Result.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class YamlSource {
 public:
  explicit YamlSource(std::string name) : name_(std::move(name)) {}

  const std::string& name() const { return name_; }
  // "file:line:column" of a node (1-based, as editors count).
  std::string where(const YAML::Node& node) const;
  [[noreturn]] void fail(const YAML::Node& node, std::string_view what) const;

  YAML::Node parse(const std::string& text) const;  // syntax errors become ConfigError
  void expect_map(const YAML::Node& node, std::string_view what) const;
  void expect_sequence(const YAML::Node& node, std::string_view what) const;
  void check_keys(const YAML::Node& map, std::string_view what, std::initializer_list<std::string_view> allowed) const;

  template <class T>
  T required(const YAML::Node& map, std::string_view key, std::string_view what) const {
    const YAML::Node node = map[std::string(key)];
    if (!node) fail(map, std::string(what) + ": missing required key '" + std::string(key) + "'");
    return as<T>(node, key);
  }

  template <class T>
  std::optional<T> optional(const YAML::Node& map, std::string_view key) const {
    const YAML::Node node = map[std::string(key)];
    if (!node) return std::nullopt;
    return as<T>(node, key);
  }

  template <class T>
  T as(const YAML::Node& node, std::string_view key) const {
    try {
      return node.as<T>();
    } catch (const YAML::Exception&) {
      fail(node, "'" + std::string(key) + "' has a value of the wrong type: '" + scalar_text(node) + "'");
    }
  }

 private:
  static std::string scalar_text(const YAML::Node& node);
  std::string name_;
};

}  // namespace lb::profiles
