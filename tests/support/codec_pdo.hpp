#pragma once
// For the codec tests: the index of a PDO in a codec by its profile name (what the gateways get
// from their registration loop).

#include <gtest/gtest.h>

#include <cstddef>
#include <string>

namespace lb::test {

template <class Codec>
std::size_t pdo_index(const Codec& codec, const std::string& name) {
  for (std::size_t i = 0; i < codec.pdos().size(); ++i) {
    if (codec.pdos()[i].def->name == name) return i;
  }
  ADD_FAILURE() << "no PDO " << name;
  return 0;
}

}  // namespace lb::test
