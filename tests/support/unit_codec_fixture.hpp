#pragma once
// The fixture of a codec unit test: the built-in profile of one type and version, the PDOs a node
// of it has by default, and the codec on them. The test names the PDOs it feeds by their names.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/codec_pdo.hpp"

namespace lb::test {

template <class Codec>
class CodecOnProfile : public ::testing::Test {
 protected:
  CodecOnProfile(const char* profile_id, const char* version, std::uint8_t node_id)
      : registry_(profiles::ProfileRegistry::builtin()),
        profile_(*registry_.find(profile_id, version)),
        pdos_(profiles::default_pdos(profile_, node_id)) {}

  std::size_t pdo(const std::string& name) const { return pdo_index(codec_, name); }

  profiles::ProfileRegistry registry_;
  const profiles::Profile& profile_;
  std::vector<profiles::DevicePdo> pdos_;
  Codec codec_{profile_, pdos_};
};

}  // namespace lb::test
