#include "sim/device_dictionary.hpp"

#include <algorithm>
#include <stdexcept>

#include "canopen/object_value.hpp"
#include "profiles/device_types.hpp"
#include "sim/pdo_parameters.hpp"

namespace lb::sim {

using canopen::DataType;
using canopen::ObjectAccess;

namespace {

ObjectAccess to_access(profiles::Access a) {
  switch (a) {
    case profiles::Access::ro: return ObjectAccess::ro;
    case profiles::Access::wo: return ObjectAccess::wo;
    case profiles::Access::rw: return ObjectAccess::rw;
    case profiles::Access::const_: return ObjectAccess::const_;
  }
  return ObjectAccess::ro;
}

std::vector<std::uint8_t> bytes(DataType type, const canopen::ObjectValue& v) {
  auto b = canopen::encode(type, v);
  if (!b) throw std::runtime_error("simulated dictionary: " + b.error().message);
  return *b;
}

void add(canopen::ObjectDictionary& od, std::uint16_t index, std::uint8_t sub, DataType type, ObjectAccess access,
         const canopen::ObjectValue& value) {
  if (auto r = od.add(index, sub, type, access, bytes(type, value)); !r) {
    throw std::runtime_error("simulated dictionary: " + r.error().message);
  }
}

bool has_manufacturer_entries(const profiles::Profile& profile, profiles::PdoDirection direction) {
  return std::any_of(profile.pdos.begin(), profile.pdos.end(), [direction](const profiles::PdoDef& p) {
    return p.direction == direction && (p.rules.manufacturer_entries > 0 || p.manufacturer_data);
  });
}

}  // namespace

std::uint32_t product_code(std::string_view device_type) {
  const auto* type = profiles::find_device_type(device_type);
  return type != nullptr ? type->simulated_product_code : 0;
}

std::string simulated_device_name(const profiles::DeviceConfig& device, const profiles::Profile& profile) {
  return "linebridge simulated " + profile.device + " " + device.name + " (" + profile.id + " version " +
         profile.version + ")";
}

canopen::ObjectDictionary make_device_dictionary(const profiles::DeviceConfig& device,
                                                 const profiles::Profile& profile) {
  canopen::ObjectDictionary od;
  for (const auto& o : profile.objects) {
    if (o.type == DataType::visible_string || o.type == DataType::octet_string) {
      add(od, o.index, o.sub, o.type, to_access(o.access), canopen::ObjectValue{std::string()});
      continue;
    }
    if (auto r = od.add(o.index, o.sub, o.type, to_access(o.access), {}, o.min, o.max); !r) {
      throw std::runtime_error("simulated dictionary: " + r.error().message);
    }
  }

  const auto& id = device.simulation.identity;
  add(od, 0x1000, 0, DataType::unsigned32, ObjectAccess::ro,
      std::uint64_t{id.device_type.value_or(profile.device_type)});
  add(od, 0x1001, 0, DataType::unsigned8, ObjectAccess::ro, std::uint64_t{0});
  add(od, 0x1005, 0, DataType::unsigned32, ObjectAccess::rw, std::uint64_t{canopen::cob::sync});  // CiA 301: rw
  add(od, 0x1008, 0, DataType::visible_string, ObjectAccess::const_, simulated_device_name(device, profile));
  add(od, 0x1009, 0, DataType::visible_string, ObjectAccess::const_, std::string("sim-1"));
  add(od, 0x100A, 0, DataType::visible_string, ObjectAccess::const_, std::string("linebridge-sim 0.1"));
  add(od, 0x1014, 0, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{canopen::cob::emcy_base + device.node_id});
  add(od, 0x1017, 0, DataType::unsigned16, ObjectAccess::rw,
      static_cast<std::uint64_t>(device.simulation.heartbeat_period.count()));
  add(od, 0x1018, 0, DataType::unsigned8, ObjectAccess::const_, std::uint64_t{4});
  add(od, 0x1018, 1, DataType::unsigned32, ObjectAccess::ro,
      std::uint64_t{id.vendor_id.value_or(0x4C42'0000)});  // "LB"
  add(od, 0x1018, 2, DataType::unsigned32, ObjectAccess::ro,
      std::uint64_t{id.product_code.value_or(product_code(profile.device))});
  add(od, 0x1018, 3, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{id.revision.value_or(0x0001'0000)});
  add(od, 0x1018, 4, DataType::unsigned32, ObjectAccess::ro,
      std::uint64_t{id.serial_number.value_or(0x5100'0000U + device.node_id)});
  add(od, kDeviceText, 0, DataType::visible_string, ObjectAccess::rw, std::string());
  add(od, kSimulationControl, 0, DataType::unsigned8, ObjectAccess::wo, std::uint64_t{0});
  add(od, kErrorSimulation, 0, DataType::unsigned32, ObjectAccess::wo, std::uint64_t{0});
  if (device.simulation.pre_defined_error_field) {
    add(od, kErrorField, 0, DataType::unsigned8, ObjectAccess::rw, std::uint64_t{0});
    for (std::uint8_t sub = 1; sub <= kErrorFieldEntries; ++sub) {
      add(od, kErrorField, sub, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{0});
    }
  }
  if (has_manufacturer_entries(profile, profiles::PdoDirection::tx)) {
    add(od, kSecondStatusWord, 0, DataType::unsigned16, ObjectAccess::ro, std::uint64_t{0});
  }
  if (has_manufacturer_entries(profile, profiles::PdoDirection::rx)) {
    add(od, kSecondControlWord, 0, DataType::unsigned16, ObjectAccess::rw, std::uint64_t{0});
  }
  return od;
}

}  // namespace lb::sim
