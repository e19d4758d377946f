#include "sim/device_dictionary.hpp"

#include <stdexcept>

#include "canopen/object_value.hpp"

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

}  // namespace

std::string simulated_device_name(const profiles::DeviceConfig& device, const profiles::Profile& profile) {
  return "linebridge simulated " + profile.device + " " + device.name + " (" + profile.id + " version " + profile.version + ")";
}

canopen::ObjectDictionary make_device_dictionary(const profiles::DeviceConfig& device, const profiles::Profile& profile) {
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

  add(od, 0x1000, 0, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{profile.device_type});
  add(od, 0x1001, 0, DataType::unsigned8, ObjectAccess::ro, std::uint64_t{0});
  add(od, 0x1008, 0, DataType::visible_string, ObjectAccess::const_, simulated_device_name(device, profile));
  add(od, 0x1009, 0, DataType::visible_string, ObjectAccess::const_, std::string("sim-1"));
  add(od, 0x100A, 0, DataType::visible_string, ObjectAccess::const_, std::string("linebridge-sim 0.1"));
  add(od, 0x1017, 0, DataType::unsigned16, ObjectAccess::rw,
      static_cast<std::uint64_t>(device.simulation.heartbeat_period.count()));
  // Manufacturer-specific: a free text the line can store in the device (segmented both ways).
  add(od, 0x2000, 0, DataType::visible_string, ObjectAccess::rw, std::string());
  add(od, 0x1018, 0, DataType::unsigned8, ObjectAccess::const_, std::uint64_t{4});
  add(od, 0x1018, 1, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{0x4C42'0000});  // "LB"
  add(od, 0x1018, 2, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{profile.device_type});
  add(od, 0x1018, 3, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{0x0001'0000});
  add(od, 0x1018, 4, DataType::unsigned32, ObjectAccess::ro, std::uint64_t{0x5100'0000U + device.node_id});

  // PDO parameters as CiA 301 lays them out: RPDOn at 1400h/1600h, TPDOn at 1800h/1A00h.
  std::uint16_t rx = 0, tx = 0;
  for (const auto& pdo : profile.pdos) {
    const bool is_tx = pdo.direction == profiles::PdoDirection::tx;
    const std::uint16_t n = is_tx ? tx++ : rx++;
    const std::uint16_t comm = static_cast<std::uint16_t>((is_tx ? 0x1800 : 0x1400) + n);
    const std::uint16_t map = static_cast<std::uint16_t>((is_tx ? 0x1A00 : 0x1600) + n);
    const std::uint64_t cob_id = (is_tx ? 0x4000'0000U : 0U) | pdo.cob_id(device.node_id);
    add(od, comm, 0, DataType::unsigned8, ObjectAccess::const_, std::uint64_t{5});
    add(od, comm, 1, DataType::unsigned32, ObjectAccess::rw, cob_id);
    add(od, comm, 2, DataType::unsigned8, ObjectAccess::rw, std::uint64_t{pdo.transmission_type});
    add(od, comm, 3, DataType::unsigned16, ObjectAccess::rw, std::uint64_t{0});
    add(od, comm, 5, DataType::unsigned16, ObjectAccess::rw, std::uint64_t{0});
    add(od, map, 0, DataType::unsigned8, ObjectAccess::rw, std::uint64_t{pdo.mapping.size()});
    for (std::size_t i = 0; i < pdo.mapping.size(); ++i) {
      add(od, map, static_cast<std::uint8_t>(i + 1), DataType::unsigned32, ObjectAccess::rw,
          std::uint64_t{pdo.mapping[i].to_u32()});
    }
  }
  return od;
}

}  // namespace lb::sim
