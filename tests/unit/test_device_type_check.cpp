// lb-check-device-types' check given broken inputs: each disagreement between the device-type
// registry, the profiles and the IDL's word bindings is named, in the sentence the build prints.
// The broken inputs are the built-in ones with one thing changed here; the expected sentences are
// written by hand (the saw's status word bit 0 is saw_ready in both its profiles, 6030h).
#include <gtest/gtest.h>

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "gateways/codecs/device_type_check.hpp"

namespace {

using lb::gateways::check_device_types;
using lb::profiles::Behaviour;
using lb::profiles::DeviceType;
using lb::profiles::Profile;
using lb::profiles::ProfileRegistry;

std::vector<DeviceType> builtin_types() {
  return {std::begin(lb::profiles::device_types), std::end(lb::profiles::device_types)};
}

Profile builtin_profile(const std::string& id, const std::string& version) {
  const auto registry = ProfileRegistry::builtin();
  const auto* p = registry.find(id, version);
  if (p == nullptr) throw std::logic_error("no built-in profile " + id + "@" + version);
  return *p;
}

void rename_bit(Profile& p, const std::string& word, const std::string& from, const std::string& to) {
  for (auto& set : p.bitsets) {
    if (set.name != word) continue;
    for (auto& bit : set.bits) {
      if (bit.name == from) {
        bit.name = to;
        return;
      }
    }
  }
  throw std::logic_error(p.key() + " has no " + word + " bit " + from);
}

bool has(const std::vector<std::string>& findings, const std::string& sentence) {
  return std::find(findings.begin(), findings.end(), sentence) != findings.end();
}

std::string all(const std::vector<std::string>& findings) {
  std::string out;
  for (const auto& f : findings) out += "  " + f + "\n";
  return out;
}

TEST(DeviceTypeCheck, TheBuiltInRegistryProfilesAndIdlAgree) {
  const auto findings = check_device_types(ProfileRegistry::builtin(), builtin_types());
  EXPECT_TRUE(findings.empty()) << all(findings);
}

TEST(DeviceTypeCheck, AProfileBitTheIdlDoesNotDeclareAndAFieldNoProfileNamesAreBothNamed) {
  auto registry = ProfileRegistry::builtin();
  for (const char* version : {"1.0", "3.1"}) {
    auto saw = builtin_profile("cia420-4", version);
    rename_bit(saw, "status_word", "saw_ready", "saw_is_ready");
    registry.add(saw);  // replaces the built-in one of the same id and version
  }
  const auto findings = check_device_types(registry, builtin_types());
  EXPECT_EQ(findings.size(), 3u) << all(findings);
  EXPECT_TRUE(has(findings,
                  "saw: profile cia420-4@1.0 names status_word bit 'saw_is_ready', which idl/saw.idl's status_word "
                  "does not declare"))
      << all(findings);
  EXPECT_TRUE(has(findings,
                  "saw: profile cia420-4@3.1 names status_word bit 'saw_is_ready', which idl/saw.idl's status_word "
                  "does not declare"))
      << all(findings);
  EXPECT_TRUE(
      has(findings, "saw: idl/saw.idl declares status_word field 'saw_ready', which no profile of the type names"))
      << all(findings);
}

TEST(DeviceTypeCheck, AFieldOneProfileStillNamesIsNotAFinding) {
  auto registry = ProfileRegistry::builtin();
  auto saw = builtin_profile("cia420-4", "3.1");
  rename_bit(saw, "status_word", "saw_ready", "saw_is_ready");
  registry.add(saw);
  const auto findings = check_device_types(registry, builtin_types());
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0],
            "saw: profile cia420-4@3.1 names status_word bit 'saw_is_ready', which idl/saw.idl's status_word does not "
            "declare");
}

TEST(DeviceTypeCheck, AProfileOfAnUnregisteredTypeIsNamed) {
  auto registry = ProfileRegistry::builtin();
  auto ghost = builtin_profile("cia420-2", "1.0");
  ghost.id = "lb-ghost";
  ghost.device = "ghost";
  registry.add(ghost);
  const auto findings = check_device_types(registry, builtin_types());
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0], "profile lb-ghost@1.0 is for device type 'ghost', which profiles/device_types.hpp lacks");
}

TEST(DeviceTypeCheck, AProfileVersionTheEntryDoesNotListIsNamed) {
  auto registry = ProfileRegistry::builtin();
  auto saw = builtin_profile("cia420-4", "3.1");
  saw.version = "9.9";
  registry.add(saw);
  const auto findings = check_device_types(registry, builtin_types());
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0], "profile cia420-4@9.9 is for a saw, whose entry says cia420-4 versions 1.0, 3.1");
}

TEST(DeviceTypeCheck, AnEntryWithoutItsProfileIsNamed) {
  auto types = builtin_types();
  // "none": an IDL without a word binding, so the missing profile is the only finding.
  types.push_back({"ghost", "lb-ghost", "2.0", "none", Behaviour::feeder, "a type without its profile", 0});
  const auto findings = check_device_types(ProfileRegistry::builtin(), types);
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0], "ghost: no built-in profile lb-ghost@2.0 for it");
}

TEST(DeviceTypeCheck, ADriveWhoseIdlHasNoDriveShapeIsNamed) {
  auto types = builtin_types();
  // The saw's IDL has a word binding, but not the drive's shape (no speed set value).
  types.push_back({"ghost", "cia420-4", "3.1", "saw", Behaviour::drive, "a drive entry on the saw's IDL", 0});
  const auto findings = check_device_types(ProfileRegistry::builtin(), types);
  EXPECT_TRUE(
      has(findings, "ghost: idl/saw.idl declares no drive-shaped {Name}Status, StatusWord, ControlWord, Setpoint"))
      << all(findings);
  // And the saw's profile is a saw's, not this entry's.
  EXPECT_TRUE(has(findings, "ghost: no built-in profile cia420-4@3.1 for it")) << all(findings);
}

}  // namespace
