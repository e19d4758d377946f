#pragma once
// Where an executable's line configuration comes from: the file given with --config, or the
// demo line compiled into the binary (config/lines/demo.yaml).

#include <span>
#include <string>
#include <string_view>
#include <utility>

#include "profiles/line_config.hpp"

namespace lb::app {

std::span<const std::pair<std::string_view, std::string_view>> builtin_line_texts();

// Exits start-up with the message on error (the caller prints it and returns non-zero).
inline Result<profiles::LineConfig> load_config(const std::string& path, const profiles::ProfileRegistry& registry) {
  if (!path.empty()) return profiles::load_line_config(path, registry);
  const auto demo = builtin_line_texts().front();
  return profiles::parse_line_config(std::string(demo.second), "built-in " + std::string(demo.first), registry);
}

// What serves: "line file /etc/linebridge/line.yaml" or "the built-in demo line (...)", for the
// start-up log of the bridge and the simulator (a forgotten --config must not go unnoticed).
inline std::string config_source_text(const std::string& path) {
  if (!path.empty()) return "line file " + path;
  return "the built-in demo line (" + std::string(builtin_line_texts().front().first) +
         "; --config or LINEBRIDGE_CONFIG names another)";
}

}  // namespace lb::app
