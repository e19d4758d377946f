#pragma once
// The holds on a line's devices that outlive a run of the bridge: an operator's NMT stop or enter
// pre-operational, and the line's `when_mandatory_fails: stop_others` stop. A restarted bridge
// that forgot them would NMT-start a machine an operator had stopped. Keyed, like the set values,
// by what the device is (bus, node-ID, profile), with who holds it, why and since when.
//
// The file, <state_dir>/<line>.holds, text, one device a line after a "format N" line:
//   bus node-ID profile holder since(Unix s) reason...
// holder: operator-stop, operator-pre-operational or line-stop; reason: the rest of the line ("-"
// when there is none). A file of another format restores nothing (logged): a hold this bridge
// cannot read is not guessed at.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "canopen/nmt.hpp"

namespace lb::gateways {

struct KeptHold {
  static constexpr int kFormat = 1;

  struct Key {
    std::string bus;
    unsigned node_id = 0;
    std::string profile;  // id@version
    // NOLINTNEXTLINE(modernize-use-nullptr): clang-tidy 14 misreads a defaulted <=>
    auto operator<=>(const Key&) const = default;
  };
  enum class Holder { operator_stop, operator_pre_operational, line_stop };

  Holder holder = Holder::operator_stop;
  std::int64_t since_s = 0;  // Unix time the hold was set
  std::string reason;        // line-stop: the mandatory device and what happened to it

  bool operator==(const KeptHold&) const = default;
  // The NMT state the hold keeps the device in: what its boots send instead of NMT start.
  canopen::NmtCommand command() const {
    return holder == Holder::operator_pre_operational ? canopen::NmtCommand::enter_pre_operational
                                                      : canopen::NmtCommand::stop;
  }
};

std::string_view to_string(KeptHold::Holder holder);
// "held stopped by an operator's nmt stop since 2024-05-01 10:00:00 UTC" and the like.
std::string describe(const KeptHold& hold);
// Unix seconds as "2024-05-01 10:00:00 UTC".
std::string utc_text(std::int64_t unix_s);

// The file's text for these holds.
std::string holds_text(const std::map<KeptHold::Key, KeptHold>& holds);
// What a file's text holds; lines it cannot parse are skipped (a few logged, then a summary), and
// a file without this format's "format" line restores nothing. `why` says what was not restored
// (empty when everything was).
std::map<KeptHold::Key, KeptHold> parse_holds(const std::string& text, const std::string& path, std::string& why);

}  // namespace lb::gateways
