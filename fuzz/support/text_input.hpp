#pragma once
// What the text-reading fuzz targets (EDS, profile, line file) share: the input as text, and the
// rule that a refusal says why (an empty message is a defect, reported as a crash).
#include <cstddef>
#include <cstdint>
#include <string>

namespace lb::fuzz {

inline std::string as_text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

// True if parsed holds a value; traps if it holds an error without a message.
template <class Result>
bool accepted(const Result& parsed) {
  if (!parsed && parsed.error().message.empty()) __builtin_trap();
  return static_cast<bool>(parsed);
}

}  // namespace lb::fuzz
