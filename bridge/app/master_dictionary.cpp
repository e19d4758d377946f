#include "app/master_dictionary.hpp"

#include <stdexcept>

#include "canopen/object_value.hpp"

namespace lb::app {

namespace {

canopen::ObjectDictionary::Bytes le(std::uint64_t value, std::size_t size) {
  canopen::ObjectDictionary::Bytes b(size);
  for (std::size_t i = 0; i < size; ++i) b[i] = static_cast<std::uint8_t>(value >> (8 * i));
  return b;
}

void add(canopen::ObjectDictionary& od, std::uint16_t index, std::uint8_t sub, canopen::DataType type,
         std::uint64_t value) {
  const auto size = canopen::sdo_size(type);
  if (auto r = od.add(index, sub, type, canopen::ObjectAccess::ro, le(value, size)); !r)
    throw std::logic_error(r.error().message);
}

}  // namespace

canopen::ObjectDictionary master_dictionary(const profiles::BusConfig& bus) {
  using canopen::DataType;
  constexpr std::uint32_t kNmtMaster = 0x01;
  constexpr std::uint32_t kFlyingMaster = 0x20;
  canopen::ObjectDictionary od;
  add(od, 0x1000, 0, DataType::unsigned32, 0);
  add(od, 0x1001, 0, DataType::unsigned8, 0);
  add(od, 0x1017, 0, DataType::unsigned16, static_cast<std::uint64_t>(bus.master_heartbeat_period.count()));
  const bool flying = bus.role == profiles::BusRole::standby;
  add(od, 0x1F80, 0, DataType::unsigned32, kNmtMaster | (flying ? kFlyingMaster : 0));
  if (flying) {
    const auto& f = bus.flying;
    add(od, 0x1F90, 0, DataType::unsigned8, 6);
    const auto ms = [](std::chrono::milliseconds v) { return static_cast<std::uint64_t>(v.count()); };
    add(od, 0x1F90, 1, DataType::unsigned16, ms(f.detect_timeout));
    add(od, 0x1F90, 2, DataType::unsigned16, ms(f.negotiation_delay));
    add(od, 0x1F90, 3, DataType::unsigned16, f.priority);
    add(od, 0x1F90, 4, DataType::unsigned16, ms(f.priority_slot));
    add(od, 0x1F90, 5, DataType::unsigned16, ms(f.device_slot));
    add(od, 0x1F90, 6, DataType::unsigned16, ms(f.detect_cycle));
  }
  return od;
}

}  // namespace lb::app
