#pragma once
// A device's status and control words as text, by the field names of its word binding
// (msgs/word_bindings.hpp, generated from its IDL), for linebridge-cli: a drive type or the saw
// needs no bit table of its own.

#include <fmt/format.h>

#include <algorithm>
#include <string>
#include <string_view>

#include "msgs/word_bindings.hpp"

namespace lb::app {

// The status word's flags that are set and its code fields that report something, by IDL name.
template <class Binding>
std::string status_word_text(const typename Binding::StatusWord& w) {
  std::string out;
  const auto add = [&out](std::string_view part) {
    if (!out.empty()) out += ' ';
    out += part;
  };
  for (const auto& f : Binding::status_flags) {
    if ((w.*f.get)()) add(f.name);
  }
  for (const auto& c : Binding::status_codes) {
    if (const auto code = c.get(w); !code.empty()) add(fmt::format("{}={}", c.name, code));
  }
  return out;
}

// The momentary commands the control word carries now (pressed like buttons). A toggle is none:
// its every change is the command, so its level says nothing is held (toggles_text shows it).
template <class Binding>
std::string pressed_text(const typename Binding::ControlWord& c) {
  std::string out;
  for (const auto& f : Binding::control_flags) {
    if ((c.*f.get)() && std::ranges::find(Binding::momentary, f.name) != Binding::momentary.end())
      out += (out.empty() ? "" : " ") + std::string(f.name);
  }
  return out;
}

// The control word's toggles with their level now, "change_of_length=1": the level is the state
// of the toggle (what the last change made it), never a button held.
template <class Binding>
std::string toggles_text(const typename Binding::ControlWord& c) {
  std::string out;
  for (const auto& f : Binding::control_flags) {
    if (std::ranges::find(Binding::toggles, f.name) != Binding::toggles.end())
      out += fmt::format("{}{}={}", out.empty() ? "" : " ", f.name, (c.*f.get)() ? 1 : 0);
  }
  return out;
}

}  // namespace lb::app
