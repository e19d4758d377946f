#include "app/eds_tool.hpp"

#include <fmt/format.h>

#include <optional>
#include <vector>

#include "app/arguments.hpp"
#include "canopen/pdo_mapping.hpp"
#include "profiles/eds.hpp"

namespace lb::app {
namespace {

using profiles::EdsEntry;
using profiles::EdsFile;

bool eds_readable(const std::string& a) { return a == "ro" || a == "rw" || a == "rwr" || a == "rww" || a == "const"; }
bool eds_writable(const std::string& a) { return a == "wo" || a == "rw" || a == "rwr" || a == "rww"; }
bool eds_fixed(const std::string& a) { return a == "ro" || a == "const"; }

struct Findings {
  std::vector<std::string> problems;  // the device does not fit the profile
  std::vector<std::string> notes;
};

void check_objects(const EdsFile& eds, const profiles::Profile& profile, Findings& f) {
  for (const auto& obj : profile.objects) {
    const EdsEntry* e = eds.find(obj.index, obj.sub);
    const auto what = fmt::format("{:04X}h sub {} {}", obj.index, obj.sub, obj.name);
    if (e == nullptr) {
      (obj.mandatory ? f.problems : f.notes)
          .push_back(what + ": not in the file" + (obj.mandatory ? "" : " (optional in the profile)"));
      continue;
    }
    if (e->type && *e->type != obj.type) {
      f.problems.push_back(fmt::format("{}: data type {} ({:04X}h) in the file, {} in the profile ({})", what,
                                       canopen::to_string(*e->type), e->type_code, canopen::to_string(obj.type),
                                       e->where));
    } else if (!e->type) {
      f.problems.push_back(fmt::format("{}: data type {:04X}h in the file, {} in the profile ({})", what, e->type_code,
                                       canopen::to_string(obj.type), e->where));
    }
    if (obj.readable() && !eds_readable(e->access)) {
      f.problems.push_back(what + ": the profile reads it, the file says access '" + e->access + "' (" + e->where +
                           ")");
    }
    if (obj.writable() && !eds_writable(e->access)) {
      f.problems.push_back(what + ": the profile writes it, the file says access '" + e->access + "' (" + e->where +
                           ")");
    }
  }
  for (const auto& pdo : profile.pdos) {
    for (const auto& entry : pdo.mapping) {
      if (entry.is_dummy()) continue;
      const EdsEntry* e = eds.find(entry.index, entry.sub);
      if (e != nullptr && !e->pdo_mapping) {
        f.problems.push_back(
            fmt::format("{:04X}h sub {} ({}): the profile maps it in {}, the file says PDOMapping=0 ({})", entry.index,
                        entry.sub, e->name, pdo.name, e->where));
      }
    }
  }
}

std::string hex32(std::uint64_t v) { return fmt::format("0x{:08X}", v); }

// The device's own PDO defaults against what the line will use: the override that makes the line
// use the device's, entry by entry.
std::vector<std::string> pdo_overrides(const EdsFile& eds, const profiles::Profile& profile,
                                       const std::vector<profiles::DevicePdo>& line_pdos,
                                       std::optional<std::uint8_t> node, Findings& f) {
  std::vector<std::string> out;
  for (const auto& pdo : line_pdos) {
    const auto* def = profile.pdo(pdo.name);
    if (def == nullptr) continue;
    const std::uint16_t comm = def->communication_index();
    const std::uint16_t map = def->mapping_index();
    const auto get = [&](std::uint16_t index, std::uint8_t sub) -> std::optional<std::uint64_t> {
      auto v = eds.value(index, sub, node);
      if (!v) {
        f.problems.push_back(v.error().message);
        return std::nullopt;
      }
      return *v;
    };
    const auto fixed = [&](std::uint16_t index, std::uint8_t sub) {
      const auto* e = eds.find(index, sub);
      return e != nullptr && eds_fixed(e->access);
    };
    if (eds.find(comm, 1) == nullptr) {
      (def->mandatory ? f.problems : f.notes).push_back(fmt::format("{} ({:04X}h): not in the file", pdo.name, comm));
      continue;
    }
    std::vector<std::string> keys;
    const auto differ = [&](const char* key, std::uint64_t device, std::uint64_t line, std::uint16_t index,
                            std::uint8_t sub, const std::string& text) {
      if (device == line) return;
      keys.push_back(fmt::format("{}: {}", key, text));
      if (fixed(index, sub)) {
        f.notes.push_back(
            fmt::format("{} {}: the device fixes it ({}) and the line would use another value: keep this override",
                        pdo.name, key, eds.find(index, sub)->access));
      }
    };
    if (auto cob = get(comm, 1)) differ("cob_id", *cob, pdo.cob_id_entry(), comm, 1, hex32(*cob));
    if (auto tt = get(comm, 2)) differ("transmission_type", *tt, pdo.transmission_type, comm, 2, std::to_string(*tt));
    if (pdo.direction == profiles::PdoDirection::tx) {
      if (auto inhibit = get(comm, 3)) {
        differ("inhibit_time_100us", *inhibit, static_cast<std::uint64_t>(pdo.inhibit.count() / 100), comm, 3,
               std::to_string(*inhibit));
      }
    }
    if (auto timer = get(comm, 5))
      differ("event_timer_ms", *timer, static_cast<std::uint64_t>(pdo.event_timer.count()), comm, 5,
             std::to_string(*timer));
    if (auto count = get(map, 0); count && *count > canopen::PdoMapping::kMaxEntries) {
      f.problems.push_back(fmt::format("{} mapping ({:04X}h): {} entries", pdo.name, map, *count));
    } else if (count) {
      std::vector<canopen::PdoEntry> mapping;
      bool known = true;
      for (unsigned i = 1; i <= *count; ++i) {
        auto v = get(map, static_cast<std::uint8_t>(i));  // at most kMaxEntries (64)
        if (!v) {
          known = false;
          break;
        }
        const auto entry = canopen::PdoEntry::from_u32(static_cast<std::uint32_t>(*v));
        if (!entry.is_dummy() && profile.object(entry.index, entry.sub) == nullptr) {
          f.notes.push_back(
              fmt::format("{}: the device maps {:04X}h sub {} by default, which profile {} does not define: "
                          "keep the profile's mapping (the bridge writes it at boot)",
                          pdo.name, entry.index, entry.sub, profile.key()));
          known = false;
          break;
        }
        mapping.push_back(entry);
      }
      if (known && mapping != pdo.mapping) {
        std::string text;
        for (const auto& e : mapping) text += (text.empty() ? "" : ", ") + hex32(e.to_u32());
        keys.push_back("mapping: [" + text + "]");
        if (fixed(map, 1)) f.notes.push_back(pdo.name + " mapping: the device fixes it: keep this override");
      }
    }
    if (keys.empty()) continue;
    std::string line;
    for (const auto& k : keys) line += (line.empty() ? "" : ", ") + k;
    out.push_back(fmt::format("      {}: {{{}}}", pdo.name, line));
  }
  return out;
}

}  // namespace

int run_eds(const profiles::LineConfig& line, const profiles::ProfileRegistry& builtin, const EdsOptions& o) {
  auto eds = profiles::load_eds(o.file);
  if (!eds) return fmt::print(stderr, "{}\n", eds.error().message), kExitUsage;
  const profiles::ProfileRegistry& registry = line.profiles ? *line.profiles : builtin;

  const profiles::Profile* profile = nullptr;
  const profiles::DeviceConfig* device = nullptr;
  if (!o.device.empty()) {
    device = line.device(o.device);
    if (device == nullptr) return fmt::print(stderr, "no device {} in line {}\n", o.device, line.line), kExitUsage;
    profile = device->resolved_profile;
  } else if (!o.profile.empty() && !o.profile_version.empty()) {
    profile = registry.find(o.profile, o.profile_version);
    if (profile == nullptr)
      return fmt::print(stderr, "unknown profile {} version {}\n", o.profile, o.profile_version), kExitUsage;
  } else {
    std::string candidates;
    auto type = eds->value(0x1000, 0, std::nullopt);
    for (const auto& p : registry.profiles()) {
      if (type && *type && (**type & 0xFFFF) == (p.device_type & 0xFFFF)) candidates += " " + p.key();
    }
    return fmt::print(stderr, "give --device NAME (a device of the line) or --profile ID --profile-version V{}\n",
                      candidates.empty() ? std::string() : "; profiles of this device type:" + candidates),
           kExitUsage;
  }
  std::optional<std::uint8_t> node;
  if (o.node_id != 0)
    node = static_cast<std::uint8_t>(o.node_id);
  else if (eds->node_id)
    node = eds->node_id;
  else if (device != nullptr)
    node = device->node_id;

  fmt::print("{}: {} {} (vendor {}, product {}, revision {})\n", o.file, eds->vendor_name, eds->product_name,
             eds->vendor_number ? hex32(*eds->vendor_number) : "?",
             eds->product_number ? hex32(*eds->product_number) : "?",
             eds->revision_number ? hex32(*eds->revision_number) : "?");
  fmt::print("against profile {} ({}, {}){}{}\n", profile->key(), profile->device, profile->title,
             device != nullptr ? ", device " + device->name : "", node ? fmt::format(", node-ID {}", *node) : "");

  Findings f;
  std::optional<std::uint64_t> device_type;
  if (auto t = eds->value(0x1000, 0, node); !t)
    f.problems.push_back(t.error().message);
  else
    device_type = *t;
  if (!device_type) {
    f.problems.emplace_back("1000h (device type): no default value in the file");
  } else if ((*device_type & 0xFFFF) != (profile->device_type & 0xFFFF)) {
    f.problems.push_back(
        fmt::format("1000h device type {:08X}h: profile number {} in the file, {} in {} (boot error C)", *device_type,
                    *device_type & 0xFFFF, profile->device_type & 0xFFFF, profile->key()));
  }
  check_objects(*eds, *profile, f);
  const auto line_pdos = device != nullptr ? device->pdos : profiles::default_pdos(*profile, node.value_or(0));
  std::vector<std::string> overrides;
  if (node)
    overrides = pdo_overrides(*eds, *profile, line_pdos, node, f);
  else
    f.notes.emplace_back("no node-ID (--node-id, a DCF's NodeID or --device): PDO COB-IDs with $NODEID not compared");

  for (const auto& p : f.problems) fmt::print("  does not fit: {}\n", p);
  for (const auto& n : f.notes) fmt::print("  note: {}\n", n);
  fmt::print("line-file entries{}:\n", device != nullptr ? " for " + device->name : "");
  fmt::print("    identity:\n");
  if (device_type) fmt::print("      device_type: {}\n", hex32(*device_type));
  if (auto v = eds->value(0x1018, 1, node); v && *v)
    fmt::print("      vendor_id: {}\n", hex32(**v));
  else if (eds->vendor_number)
    fmt::print("      vendor_id: {}\n", hex32(*eds->vendor_number));
  if (auto v = eds->value(0x1018, 2, node); v && *v)
    fmt::print("      product_code: {}\n", hex32(**v));
  else if (eds->product_number)
    fmt::print("      product_code: {}\n", hex32(*eds->product_number));
  if (auto v = eds->value(0x1018, 3, node); v && *v)
    fmt::print("      revision: {}\n", hex32(**v));
  else if (eds->revision_number)
    fmt::print("      revision: {}\n", hex32(*eds->revision_number));
  // A serial number identifies one device: only a DCF (one configured device) states it.
  if (const auto* serial = eds->find(0x1018, 4); serial != nullptr && !serial->parameter_value.empty()) {
    if (auto v = profiles::eds_number(serial->parameter_value, node))
      fmt::print("      serial_number: {}\n", hex32(*v));
  }
  if (!overrides.empty()) {
    fmt::print(
        "    pdos:   # the device's own defaults where the line would use others: with them the bridge decodes\n"
        "            # and sends as the device does and writes nothing at boot; without them it writes the line's\n");
    for (const auto& l : overrides) fmt::print("{}\n", l);
  }
  return f.problems.empty() ? kExitOk : kExitFailure;
}

}  // namespace lb::app
