#pragma once
// CiA 301 predefined connection set: the COB-IDs every service uses by default.

#include <cstdint>
#include <string_view>

namespace lb::canopen::cob {

inline constexpr std::uint32_t nmt = 0x000;
inline constexpr std::uint32_t sync = 0x080;
inline constexpr std::uint32_t emcy_base = 0x080;
inline constexpr std::uint32_t tpdo1_base = 0x180;
inline constexpr std::uint32_t rpdo1_base = 0x200;
inline constexpr std::uint32_t sdo_tx_base = 0x580;  // server -> client
inline constexpr std::uint32_t sdo_rx_base = 0x600;  // client -> server
inline constexpr std::uint32_t heartbeat_base = 0x700;
// CiA 302-2 flying-master services.
inline constexpr std::uint32_t active_master_answer = 0x071;  // [priority, node-ID]
inline constexpr std::uint32_t negotiation_request = 0x072;
inline constexpr std::uint32_t active_master_request = 0x073;
inline constexpr std::uint32_t force_negotiation = 0x076;
inline constexpr std::uint32_t flying_master_first = 0x071;
inline constexpr std::uint32_t flying_master_last = 0x076;

// Number of 11-bit identifiers: the size of the flat dispatch table.
inline constexpr std::uint32_t kStandardIdCount = 0x800;

// What CiA 301 keeps an 11-bit identifier for when no configurable object (a PDO) may use it
// (the restricted CAN-IDs of the predefined connection set), or "" when a PDO may.
constexpr std::string_view restricted_use(std::uint32_t id) {
  if (id == nmt) return "NMT";
  if (id < sync) return "reserved";
  if (id == sync) return "SYNC";
  if (id <= 0x0FF) return "EMCY";
  if (id == 0x100) return "TIME";
  if (id <= 0x180) return "reserved";
  if (id > sdo_tx_base && id < sdo_rx_base) return "default SDO (server to client)";
  if (id > sdo_rx_base && id < 0x680) return "default SDO (client to server)";
  if (id >= 0x6E0 && id < heartbeat_base) return "reserved";
  if (id > heartbeat_base && id < 0x780) return "NMT error control (heartbeat)";
  if (id >= 0x780 && id < kStandardIdCount) return "reserved";
  return "";
}

}  // namespace lb::canopen::cob
