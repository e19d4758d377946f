// lb-check-device-types: run by the build (bridge/gateways/CMakeLists.txt), fails it when the
// device-type registry (profiles/device_types.hpp), the built-in profiles (config/profiles/) and
// the word bindings generated from the IDL (msgs/word_bindings.hpp) disagree:
//   - every built-in profile names a registered type, of the entry's profile id and versions;
//   - every registered type and version has its built-in profile;
//   - a drive type's IDL declares a drive-shaped binding; any type's word binding (drives, saw)
//     and its profiles' status and control word bits are the same names: a bit no field shows would be dropped
//     silently, a field no profile names would never be set.
// Prints every disagreement, one a line, then exits 1.
#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "gateways/codecs/drive_binding.hpp"
#include "profiles/device_types.hpp"
#include "profiles/profile_registry.hpp"

namespace {

using lb::profiles::DeviceType;
using lb::profiles::Profile;

std::vector<std::string> split_versions(std::string_view text) {
  std::vector<std::string> out;
  while (!text.empty()) {
    const auto comma = text.find(',');
    auto item = text.substr(0, comma);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    if (!item.empty()) out.emplace_back(item);
    text = comma == std::string_view::npos ? std::string_view() : text.substr(comma + 1);
  }
  return out;
}

template <class Fields, class Codes>
std::set<std::string> field_names(const Fields& flags, const Codes& codes) {
  std::set<std::string> out;
  for (const auto& f : flags) out.emplace(f.name);
  for (const auto& c : codes) out.emplace(c.name);
  return out;
}

// One word of a drive type: its IDL fields against the bits of every profile of the type.
void check_word(const DeviceType& type, std::string_view word, const std::set<std::string>& fields,
                const std::vector<const Profile*>& profiles, std::vector<std::string>& findings) {
  std::set<std::string> named;
  for (const auto* p : profiles) {
    const auto* set = p->bitset(word);
    if (set == nullptr) {
      findings.push_back(fmt::format("{}: profile {} has no {} bit set", type.name, p->key(), word));
      continue;
    }
    for (const auto& bit : set->bits) {
      named.insert(bit.name);
      if (!fields.contains(bit.name)) {
        findings.push_back(fmt::format("{}: profile {} names {} bit '{}', which idl/{}.idl's {} does not declare",
                                       type.name, p->key(), word, bit.name, type.idl, word));
      }
    }
  }
  for (const auto& f : fields) {
    if (!named.contains(f)) {
      findings.push_back(fmt::format("{}: idl/{}.idl declares {} field '{}', which no profile of the type names",
                                     type.name, type.idl, word, f));
    }
  }
}

}  // namespace

int main() {
  const auto registry = lb::profiles::ProfileRegistry::builtin();
  std::vector<const Profile*> builtin;
  for (const auto& key : registry.keys()) {
    const auto at = key.find('@');
    builtin.push_back(registry.find(key.substr(0, at), key.substr(at + 1)));
  }
  std::vector<std::string> findings;
  for (const auto* p : builtin) {
    const auto* type = lb::profiles::find_device_type(p->device);
    if (type == nullptr) {
      findings.push_back(fmt::format("profile {} is for device type '{}', which profiles/device_types.hpp lacks",
                                     p->key(), p->device));
      continue;
    }
    const auto versions = split_versions(type->versions);
    if (p->id != type->profile_id || std::find(versions.begin(), versions.end(), p->version) == versions.end()) {
      findings.push_back(fmt::format("profile {} is for a {}, whose entry says {} versions {}", p->key(), p->device,
                                     type->profile_id, type->versions));
    }
  }
  for (const auto& type : lb::profiles::device_types) {
    std::vector<const Profile*> of_type;
    for (const auto& version : split_versions(type.versions)) {
      const auto* p = registry.find(type.profile_id, version);
      if (p == nullptr || p->device != type.name) {
        findings.push_back(fmt::format("{}: no built-in profile {}@{} for it", type.name, type.profile_id, version));
      } else {
        of_type.push_back(p);
      }
    }
    // Every type whose IDL declares a word binding (the drives, the saw): its word fields against
    // its profiles' bits, the ones its codec decodes by.
    linebridge_msgs::bindings::visit(type.idl, [&]<class Binding>() {
      check_word(type, "status_word", field_names(Binding::status_flags, Binding::status_codes), of_type, findings);
      check_word(type, "control_word", field_names(Binding::control_flags, Binding::control_codes), of_type, findings);
    });
    if (type.behaviour == lb::profiles::Behaviour::drive && !lb::gateways::visit_drive(type.idl, []<class>() {})) {
      findings.push_back(
          fmt::format("{}: idl/{}.idl declares no drive-shaped {{Name}}Status, StatusWord, ControlWord, Setpoint",
                      type.name, type.idl));
    }
  }
  for (const auto& f : findings) std::fprintf(stderr, "device types: %s\n", f.c_str());
  return findings.empty() ? 0 : 1;
}
