#include "gateways/persistence/kept_holds.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <ctime>
#include <sstream>

namespace lb::gateways {

namespace {

constexpr unsigned kLoggedBadHoldLines = 3;

std::optional<KeptHold::Holder> holder_of(std::string_view s) {
  for (auto h :
       {KeptHold::Holder::operator_stop, KeptHold::Holder::operator_pre_operational, KeptHold::Holder::line_stop}) {
    if (s == to_string(h)) return h;
  }
  return std::nullopt;
}

template <class T>
bool parse_int(const std::string& s, T& out) {
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && end == s.data() + s.size();
}

// A reason is the rest of its line: no line breaks or other control characters in it.
std::string one_line(std::string s) {
  std::replace_if(
      s.begin(), s.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7F; }, ' ');
  return s;
}

std::optional<std::pair<KeptHold::Key, KeptHold>> parse_hold_line(const std::string& text) {
  std::stringstream fields(text);
  std::string bus, node, profile, holder, since;
  fields >> bus >> node >> profile >> holder >> since;
  std::string reason;
  std::getline(fields >> std::ws, reason);
  if (since.empty() || reason.empty()) return std::nullopt;
  KeptHold::Key key{bus, 0, profile};
  if (!parse_int(node, key.node_id) || key.node_id < 1 || key.node_id > 127) return std::nullopt;
  KeptHold hold;
  const auto h = holder_of(holder);
  if (!h || !parse_int(since, hold.since_s)) return std::nullopt;
  hold.holder = *h;
  hold.reason = reason == "-" ? std::string() : reason;
  return std::pair{std::move(key), std::move(hold)};
}

}  // namespace

std::string_view to_string(KeptHold::Holder holder) {
  switch (holder) {
    case KeptHold::Holder::operator_stop: return "operator-stop";
    case KeptHold::Holder::operator_pre_operational: return "operator-pre-operational";
    case KeptHold::Holder::line_stop: return "line-stop";
  }
  return "?";
}

std::string utc_text(std::int64_t unix_s) {
  const auto t = static_cast<std::time_t>(unix_s);
  std::tm tm{};
  if (::gmtime_r(&t, &tm) == nullptr) return fmt::format("{} (Unix time)", unix_s);
  char buf[32];
  if (std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S UTC", &tm) == 0) return fmt::format("{} (Unix time)", unix_s);
  return buf;
}

std::string describe(const KeptHold& hold) {
  switch (hold.holder) {
    case KeptHold::Holder::operator_stop:
      return "held stopped by an operator's nmt stop since " + utc_text(hold.since_s);
    case KeptHold::Holder::operator_pre_operational:
      return "held pre-operational by an operator's nmt pre-operational since " + utc_text(hold.since_s);
    case KeptHold::Holder::line_stop:
      return "held stopped by the line since " + utc_text(hold.since_s) +
             (hold.reason.empty() ? std::string() : ": " + hold.reason);
  }
  return {};
}

std::string holds_text(const std::map<KeptHold::Key, KeptHold>& holds) {
  std::string text = fmt::format(
      "# linebridge: the holds an operator or the line put on devices, kept until an operator starts or resets\n"
      "# the device, one device a line: bus node-ID profile holder since(Unix s) reason\n"
      "format {}\n",
      KeptHold::kFormat);
  for (const auto& [k, h] : holds) {
    const auto reason = one_line(h.reason);
    text += fmt::format("{} {} {} {} {} {}\n", k.bus, k.node_id, k.profile, to_string(h.holder), h.since_s,
                        reason.empty() ? "-" : reason);
  }
  return text;
}

std::map<KeptHold::Key, KeptHold> parse_holds(const std::string& text, const std::string& path, std::string& why) {
  std::map<KeptHold::Key, KeptHold> holds;
  std::stringstream in(text);
  std::string line;
  bool format_seen = false;
  unsigned bad = 0;
  why.clear();
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.empty() || line[0] == '#') continue;
    if (line.rfind("format ", 0) == 0) {
      if (line != fmt::format("format {}", KeptHold::kFormat)) {
        why = fmt::format("{}:{}: '{}' is not this bridge's hold format ({}): no hold restored", path, n, line,
                          KeptHold::kFormat);
        spdlog::error("{}; devices held before the restart are booted and started as if never held", why);
        return {};
      }
      format_seen = true;
      continue;
    }
    if (!format_seen) {
      why = fmt::format("{}:{}: no 'format {}' line before the holds: no hold restored", path, n, KeptHold::kFormat);
      spdlog::error("{}; devices held before the restart are booted and started as if never held", why);
      return {};
    }
    auto parsed = parse_hold_line(line);
    if (!parsed) {
      if (++bad <= kLoggedBadHoldLines)
        spdlog::error("{}:{}: not a hold line, skipped: that device's hold is lost", path, n);
      continue;
    }
    holds[parsed->first] = std::move(parsed->second);
  }
  if (bad > 0) {
    why = fmt::format("{}: {} line(s) were not hold lines and were skipped (their holds are lost)", path, bad);
    if (bad > kLoggedBadHoldLines) spdlog::error("{}", why);
  }
  return holds;
}

}  // namespace lb::gateways
