#pragma once
// The profile definitions of config/profiles/, compiled into the binary (generated at build time)
// so that the executables need no installed data files.

#include <span>
#include <string_view>
#include <utility>

namespace lb::profiles {

std::span<const std::pair<std::string_view, std::string_view>> builtin_profile_texts();

}  // namespace lb::profiles
