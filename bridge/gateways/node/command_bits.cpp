#include "gateways/node/command_bits.hpp"

namespace lb::gateways {

std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names) {
  std::vector<CommandBit> out;
  for (const auto& n : names) {
    if (auto bit = control_word.bit(n)) out.push_back({n, *bit, control_word.field(n)->stopping});
  }
  return out;
}

}  // namespace lb::gateways
