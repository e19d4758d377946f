#pragma once
// The device types the bridge serves: one entry per type, a constant table. Everything above this
// layer that differs by type keys on an entry's behaviour (drive, saw, feeder), never on its name:
// gateways pick the component, the simulator the dynamics, linebridge-cli its set options and
// topics. A drive-like type is data only: its IDL (the generated word bindings, idl/), its profile
// YAML (config/profiles/) and its entry here. docs/adding-a-device-type.md walks through one.

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <string_view>

namespace lb::profiles {

// What a type does beyond its profile's objects and PDOs: each upper layer has one
// implementation per behaviour, chosen by it.
enum class Behaviour {
  // CiA 420 drive shape: status and control word, speed set value, set echo, momentary commands
  // (puller, corrugator); its DDS types come from its IDL's generated word binding.
  drive,
  saw,     // CiA 420-4: cuts, length and program set values
  feeder,  // CiA 414: a box of feeders, its own typed services
};

constexpr std::string_view to_string(Behaviour b) {
  switch (b) {
    case Behaviour::drive: return "drive";
    case Behaviour::saw: return "saw";
    case Behaviour::feeder: return "feeder";
  }
  return "?";
}

struct DeviceType {
  std::string_view name;        // a profile's `device:`, the line file's word for the type
  std::string_view profile_id;  // the CiA profile its profiles implement, e.g. "cia420-2"
  std::string_view versions;    // the built-in profile versions, comma-separated
  std::string_view idl;         // idl/<idl>.idl: its DDS types (and, for a drive, word binding)
  Behaviour behaviour;
  std::string_view description;  // linebridge-cli's one line about the type
  // 1018h sub 2 of a simulated device of this type when the line file gives no identity.
  std::uint32_t simulated_product_code;
};

inline constexpr DeviceType device_types[] = {
    {"puller", "cia420-2", "1.0, 3.0-status", "puller", Behaviour::drive,
     "CiA 420-2 puller: speed set value, extruder running, motor/clamp/f1..f3 commands", 0x0420'0002},
    {"corrugator", "cia420-3", "3.1", "corrugator", Behaviour::drive,
     "CiA 420-3 corrugator: speed set value, extruder running, drive/move/f1..f3 commands", 0x0420'0003},
    {"saw", "cia420-4", "1.0, 3.1", "saw", Behaviour::saw, "CiA 420-4 saw: program, lengths, wall thickening, cuts",
     0x0420'0004},
    {"feeder", "cia414-2", "1.1", "feeder", Behaviour::feeder,
     "CiA 414-2 weft feeder box: loom set values, feeder services", 0x0414'0002},
    {"winder", "lb-example-winder", "1.0", "winder", Behaviour::drive,
     "example winder (test-only, docs/adding-a-device-type.md): speed set value, winder/reel/f1 commands", 0x4C57'0001},
};

// The entry of the type a profile names (`device:`); null for a type the bridge does not serve.
constexpr const DeviceType* find_device_type(std::string_view name) {
  const auto* it = std::find_if(std::begin(device_types), std::end(device_types),
                                [name](const DeviceType& t) { return t.name == name; });
  return it == std::end(device_types) ? nullptr : it;
}

}  // namespace lb::profiles
