#include "base/journal_event.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

namespace lb::journal {

namespace {

// An event's spdlog source location: this file name, and in place of a line number where the
// trailer begins (+1: spdlog takes line 0 for "no location"). No pattern of the bridge prints it.
constexpr const char* kTag = "lb::journal::event";

bool plain(char c) {
  const auto u = static_cast<unsigned char>(c);
  return u > 0x20 && u != 0x7F && c != '"' && c != '\\' && c != '{' && c != '}';
}

// A value as the trailer writes it: as it is when it is one word of plain characters, else quoted
// ("..." with \" \\ and \xHH for control characters), so a reader sees it and decode() gets it back.
void put_value(std::string& out, std::string_view v) {
  if (!v.empty() && std::all_of(v.begin(), v.end(), plain)) {
    out += v;
    return;
  }
  out += '"';
  for (const char c : v) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (u < 0x20 || u == 0x7F) {
      out += fmt::format("\\x{:02X}", u);
    } else {
      out += c;
    }
  }
  out += '"';
}

void put(std::string& out, std::string_view name, std::string_view value) {
  out += ' ';
  out += name;
  out += '=';
  put_value(out, value);
}

bool name_char(char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; }

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// One value from the start of `s` (which it advances past it); nullopt when it is malformed.
std::optional<std::string> take_value(std::string_view& s) {
  std::string v;
  if (s.empty() || s.front() != '"') {
    const auto end = std::min(s.find(' '), s.size());
    v = s.substr(0, end);
    s.remove_prefix(end);
    return v.empty() ? std::nullopt : std::optional(v);
  }
  s.remove_prefix(1);
  while (!s.empty()) {
    const char c = s.front();
    s.remove_prefix(1);
    if (c == '"') return v;
    if (c != '\\') {
      v += c;
      continue;
    }
    if (s.empty()) return std::nullopt;
    const char e = s.front();
    s.remove_prefix(1);
    if (e == '"' || e == '\\') {
      v += e;
    } else if (e == 'x' && s.size() >= 2 && hex_digit(s[0]) >= 0 && hex_digit(s[1]) >= 0) {
      v += static_cast<char>(hex_digit(s[0]) * 16 + hex_digit(s[1]));
      s.remove_prefix(2);
    } else {
      return std::nullopt;
    }
  }
  return std::nullopt;  // no closing quote
}

}  // namespace

const EventKind& kind(Event event) {
  for (const auto& k : kEvents) {
    if (k.event == event) return k;
  }
  return kEvents.front();  // unreachable: every enumerator has its row (tested)
}

const EventKind* kind_named(std::string_view name) {
  for (const auto& k : kEvents) {
    if (k.name == name) return &k;
  }
  return nullptr;
}

Line encode(Event event, const Where& where, std::string_view message, std::initializer_list<Field> fields) {
  Line line;
  line.text.reserve(message.size() + 128);
  line.text = message;
  line.trailer = line.text.size();
  line.text += " {";
  line.text += kEventField;
  line.text += '=';
  line.text += kind(event).name;
  if (!where.line.empty()) put(line.text, kLine, where.line);
  if (!where.bus.empty()) put(line.text, kBus, where.bus);
  if (!where.device.empty()) put(line.text, kDevice, where.device);
  if (where.node != 0) put(line.text, kNode, fmt::format("{}", where.node));
  for (const auto& f : fields) {
    if (!f.value.empty()) put(line.text, f.name, f.value);
  }
  line.text += '}';
  return line;
}

void log(Event event, spdlog::level::level_enum level, const Where& where, std::string_view message,
         std::initializer_list<Field> fields) {
  auto* logger = spdlog::default_logger_raw();
  if (logger == nullptr || !logger->should_log(level)) return;
  const auto line = encode(event, where, message, fields);
  logger->log(spdlog::source_loc{kTag, static_cast<int>(line.trailer + 1), ""}, level,
              spdlog::string_view_t(line.text.data(), line.text.size()));
}

std::optional<Decoded> decode(const spdlog::details::log_msg& msg) {
  if (msg.source.filename == nullptr || std::strcmp(msg.source.filename, kTag) != 0 || msg.source.line <= 0)
    return std::nullopt;
  return decode(std::string_view(msg.payload.data(), msg.payload.size()),
                static_cast<std::size_t>(msg.source.line - 1));
}

std::optional<Decoded> decode(std::string_view text, std::size_t trailer) {
  if (trailer > text.size()) return std::nullopt;
  auto s = text.substr(trailer);
  if (s.size() < 3 || s.substr(0, 2) != " {" || s.back() != '}') return std::nullopt;
  s = s.substr(2, s.size() - 3);
  Decoded d;
  while (!s.empty()) {
    const auto eq = s.find('=');
    if (eq == 0 || eq == std::string_view::npos) return std::nullopt;
    const auto name = s.substr(0, eq);
    if (!std::all_of(name.begin(), name.end(), name_char)) return std::nullopt;
    s.remove_prefix(eq + 1);
    auto value = take_value(s);
    if (!value) return std::nullopt;
    if (!s.empty()) {
      if (s.front() != ' ') return std::nullopt;
      s.remove_prefix(1);
      if (s.empty()) return std::nullopt;
    }
    d.fields.emplace_back(std::string(name), std::move(*value));
  }
  if (d.fields.empty() || d.fields.front().first != kEventField) return std::nullopt;
  d.kind = kind_named(d.fields.front().second);
  if (d.kind == nullptr) return std::nullopt;
  return d;
}

}  // namespace lb::journal
