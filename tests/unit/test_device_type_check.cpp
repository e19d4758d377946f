// lb-check-device-types' check given broken inputs: each disagreement between the device-type
// registry, the profiles and the IDL's word bindings is named, in the sentence the build prints.
// The broken inputs are the built-in ones with one thing changed here; the expected sentences are
// written by hand (the saw's status word bit 0 is saw_ready in both its profiles, 6030h).
// That the built-in ones agree the build itself checks (lb-check-device-types runs in it).
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

// The findings when `profiles` are added to the built-in ones (one of the same id and version
// replaces the built-in), against the built-in registry of types.
std::vector<std::string> findings_with(const std::vector<Profile>& profiles) {
  auto registry = ProfileRegistry::builtin();
  for (const auto& p : profiles) registry.add(p);
  return check_device_types(registry, builtin_types());
}

// The findings when `type` joins the built-in registry of types, against the built-in profiles.
std::vector<std::string> findings_with(const DeviceType& type) {
  auto types = builtin_types();
  types.push_back(type);
  return check_device_types(ProfileRegistry::builtin(), types);
}

// The built-in saw profile of `version` with its status word bit saw_ready renamed.
Profile saw_with_renamed_ready_bit(const std::string& version) {
  auto saw = builtin_profile("cia420-4", version);
  rename_bit(saw, "status_word", "saw_ready", "saw_is_ready");
  return saw;
}

TEST(DeviceTypeCheck, AProfileBitTheIdlDoesNotDeclareAndAFieldNoProfileNamesAreBothNamed) {
  const auto findings = findings_with({saw_with_renamed_ready_bit("1.0"), saw_with_renamed_ready_bit("3.1")});
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
  const auto findings = findings_with({saw_with_renamed_ready_bit("3.1")});
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0],
            "saw: profile cia420-4@3.1 names status_word bit 'saw_is_ready', which idl/saw.idl's status_word does not "
            "declare");
}

TEST(DeviceTypeCheck, AProfileOfAnUnregisteredTypeIsNamed) {
  auto ghost = builtin_profile("cia420-2", "1.0");
  ghost.id = "lb-ghost";
  ghost.device = "ghost";
  const auto findings = findings_with({ghost});
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0], "profile lb-ghost@1.0 is for device type 'ghost', which profiles/device_types.hpp lacks");
}

TEST(DeviceTypeCheck, AProfileVersionTheEntryDoesNotListIsNamed) {
  auto saw = builtin_profile("cia420-4", "3.1");
  saw.version = "9.9";
  const auto findings = findings_with({saw});
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0], "profile cia420-4@9.9 is for a saw, whose entry says cia420-4 versions 1.0, 3.1");
}

TEST(DeviceTypeCheck, AnEntryWithoutItsProfileIsNamed) {
  // "none": an IDL without a word binding, so the missing profile is the only finding.
  const auto findings = findings_with(
      DeviceType{"ghost", "lb-ghost", "2.0", "none", Behaviour::feeder, "a type without its profile", 0});
  ASSERT_EQ(findings.size(), 1u) << all(findings);
  EXPECT_EQ(findings[0], "ghost: no built-in profile lb-ghost@2.0 for it");
}

TEST(DeviceTypeCheck, ADriveWhoseIdlHasNoDriveShapeIsNamed) {
  // The saw's IDL has a word binding, but not the drive's shape (no speed set value).
  const auto findings = findings_with(
      DeviceType{"ghost", "cia420-4", "3.1", "saw", Behaviour::drive, "a drive entry on the saw's IDL", 0});
  EXPECT_TRUE(
      has(findings, "ghost: idl/saw.idl declares no drive-shaped {Name}Status, StatusWord, ControlWord, Setpoint"))
      << all(findings);
  // And the saw's profile is a saw's, not this entry's.
  EXPECT_TRUE(has(findings, "ghost: no built-in profile cia420-4@3.1 for it")) << all(findings);
}

}  // namespace
