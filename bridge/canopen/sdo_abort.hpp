#pragma once
// CiA 301 SDO abort codes (the 32-bit value in bytes 4..7 of an abort frame) and their meaning.

#include <cstdint>
#include <string_view>

namespace lb::canopen::sdo_abort {

inline constexpr std::uint32_t toggle_bit_not_alternated = 0x0503'0000;
inline constexpr std::uint32_t timed_out = 0x0504'0000;
inline constexpr std::uint32_t invalid_command_specifier = 0x0504'0001;
inline constexpr std::uint32_t invalid_block_size = 0x0504'0002;
inline constexpr std::uint32_t invalid_sequence_number = 0x0504'0003;
inline constexpr std::uint32_t crc_error = 0x0504'0004;
inline constexpr std::uint32_t out_of_memory = 0x0504'0005;
inline constexpr std::uint32_t unsupported_access = 0x0601'0000;
inline constexpr std::uint32_t read_of_write_only = 0x0601'0001;
inline constexpr std::uint32_t write_to_read_only = 0x0601'0002;
inline constexpr std::uint32_t no_such_object = 0x0602'0000;
inline constexpr std::uint32_t cannot_be_mapped = 0x0604'0041;
inline constexpr std::uint32_t pdo_length_exceeded = 0x0604'0042;
inline constexpr std::uint32_t parameter_incompatibility = 0x0604'0043;
inline constexpr std::uint32_t internal_incompatibility = 0x0604'0047;
inline constexpr std::uint32_t hardware_error = 0x0606'0000;
inline constexpr std::uint32_t length_mismatch = 0x0607'0010;
inline constexpr std::uint32_t length_too_high = 0x0607'0012;
inline constexpr std::uint32_t length_too_low = 0x0607'0013;
inline constexpr std::uint32_t no_such_sub_index = 0x0609'0011;
inline constexpr std::uint32_t value_range_exceeded = 0x0609'0030;
inline constexpr std::uint32_t value_too_high = 0x0609'0031;
inline constexpr std::uint32_t value_too_low = 0x0609'0032;
inline constexpr std::uint32_t max_less_than_min = 0x0609'0036;
inline constexpr std::uint32_t resource_not_available = 0x060A'0023;
inline constexpr std::uint32_t general_error = 0x0800'0000;
inline constexpr std::uint32_t cannot_store = 0x0800'0020;
inline constexpr std::uint32_t cannot_store_local_control = 0x0800'0021;
inline constexpr std::uint32_t cannot_store_device_state = 0x0800'0022;
inline constexpr std::uint32_t no_object_dictionary = 0x0800'0023;
inline constexpr std::uint32_t no_data_available = 0x0800'0024;

}  // namespace lb::canopen::sdo_abort

namespace lb::canopen {

// The meaning of an abort code in words (CiA 301 wording, shortened); "unknown abort code" for
// codes the standard does not define.
std::string_view sdo_abort_meaning(std::uint32_t code);

}  // namespace lb::canopen
