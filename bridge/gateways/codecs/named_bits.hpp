#pragma once
// Binds the named bits of a profile bit set (status, control or configuration word) to the
// boolean fields of a generated DDS message, once at start-up, so decoding is a loop of shifts.
// Bit positions come from the profile (and so from a line configuration's override).

#include <cstdint>
#include <initializer_list>
#include <string_view>
#include <vector>

#include "profiles/profile.hpp"

namespace lb::gateways {

template <class Msg>
class NamedBits {
 public:
  using Setter = void (Msg::*)(bool);
  struct Field {
    std::string_view name;
    Setter set;
  };

  NamedBits() = default;
  // A field the profile does not name stays false (older profile versions lack newer bits).
  NamedBits(const profiles::BitSet& set, std::initializer_list<Field> fields) { bind(set, fields); }
  // Any range of {name, set} fields (a generated word binding's flags: msgs/word_bindings.hpp).
  template <class Fields>
  NamedBits(const profiles::BitSet& set, const Fields& fields) {
    bind(set, fields);
  }

  void decode(std::uint64_t word, Msg& msg) const {
    for (const auto& b : bound_) (msg.*b.set)(((word >> b.bit) & 1U) != 0);
  }

 private:
  template <class Fields>
  void bind(const profiles::BitSet& set, const Fields& fields) {
    for (const auto& f : fields) {
      if (auto bit = set.bit(f.name)) bound_.push_back({*bit, f.set});
    }
  }

  struct Bound {
    unsigned bit;
    Setter set;
  };
  std::vector<Bound> bound_;
};

}  // namespace lb::gateways
