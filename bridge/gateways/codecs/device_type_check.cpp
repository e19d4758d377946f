#include "gateways/codecs/device_type_check.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <set>
#include <string_view>

#include "gateways/codecs/drive_binding.hpp"

namespace lb::gateways {
namespace {

using profiles::DeviceType;
using profiles::Profile;

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

// One word of a type: its IDL fields against the bits of every profile of the type.
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

const DeviceType* find_type(std::span<const DeviceType> types, std::string_view name) {
  const auto it = std::find_if(types.begin(), types.end(), [name](const DeviceType& t) { return t.name == name; });
  return it == types.end() ? nullptr : &*it;
}

}  // namespace

std::vector<std::string> check_device_types(const profiles::ProfileRegistry& registry,
                                            std::span<const DeviceType> types) {
  std::vector<std::string> findings;
  for (const auto& p : registry.profiles()) {
    const auto* type = find_type(types, p.device);
    if (type == nullptr) {
      findings.push_back(
          fmt::format("profile {} is for device type '{}', which profiles/device_types.hpp lacks", p.key(), p.device));
      continue;
    }
    const auto versions = split_versions(type->versions);
    if (p.id != type->profile_id || std::find(versions.begin(), versions.end(), p.version) == versions.end()) {
      findings.push_back(fmt::format("profile {} is for a {}, whose entry says {} versions {}", p.key(), p.device,
                                     type->profile_id, type->versions));
    }
  }
  for (const auto& type : types) {
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
    if (type.behaviour == profiles::Behaviour::drive && !visit_drive(type.idl, []<class>() {})) {
      findings.push_back(
          fmt::format("{}: idl/{}.idl declares no drive-shaped {{Name}}Status, StatusWord, ControlWord, Setpoint",
                      type.name, type.idl));
    }
  }
  return findings;
}

}  // namespace lb::gateways
