#pragma once
// CiA 301 predefined connection set: the COB-IDs every service uses by default.

#include <cstdint>

namespace lb::canopen::cob {

inline constexpr std::uint32_t nmt = 0x000;
inline constexpr std::uint32_t sync = 0x080;
inline constexpr std::uint32_t emcy_base = 0x080;
inline constexpr std::uint32_t tpdo1_base = 0x180;
inline constexpr std::uint32_t rpdo1_base = 0x200;
inline constexpr std::uint32_t sdo_tx_base = 0x580;  // server -> client
inline constexpr std::uint32_t sdo_rx_base = 0x600;  // client -> server
inline constexpr std::uint32_t heartbeat_base = 0x700;

// Number of 11-bit identifiers: the size of the flat dispatch table.
inline constexpr std::uint32_t kStandardIdCount = 0x800;

}  // namespace lb::canopen::cob
