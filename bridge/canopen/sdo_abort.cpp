#include "canopen/sdo_abort.hpp"

#include <array>
#include <utility>

namespace lb::canopen {
namespace {

using Meaning = std::pair<std::uint32_t, std::string_view>;

constexpr std::array<Meaning, 31> kMeanings{{
    {sdo_abort::toggle_bit_not_alternated, "toggle bit not alternated"},
    {sdo_abort::timed_out, "SDO protocol timed out"},
    {sdo_abort::invalid_command_specifier, "client/server command specifier not valid or unknown"},
    {sdo_abort::invalid_block_size, "invalid block size (block mode)"},
    {sdo_abort::invalid_sequence_number, "invalid sequence number (block mode)"},
    {sdo_abort::crc_error, "CRC error (block mode)"},
    {sdo_abort::out_of_memory, "out of memory"},
    {sdo_abort::unsupported_access, "unsupported access to an object"},
    {sdo_abort::read_of_write_only, "attempt to read a write-only object"},
    {sdo_abort::write_to_read_only, "attempt to write a read-only object"},
    {sdo_abort::no_such_object, "object does not exist in the object dictionary"},
    {sdo_abort::cannot_be_mapped, "object cannot be mapped to the PDO"},
    {sdo_abort::pdo_length_exceeded, "number and length of the objects to be mapped would exceed the PDO length"},
    {sdo_abort::parameter_incompatibility, "general parameter incompatibility"},
    {sdo_abort::internal_incompatibility, "general internal incompatibility in the device"},
    {sdo_abort::hardware_error, "access failed due to a hardware error"},
    {sdo_abort::length_mismatch, "data type does not match, length of service parameter does not match"},
    {sdo_abort::length_too_high, "data type does not match, length of service parameter too high"},
    {sdo_abort::length_too_low, "data type does not match, length of service parameter too low"},
    {sdo_abort::no_such_sub_index, "sub-index does not exist"},
    {sdo_abort::value_range_exceeded, "value range of parameter exceeded"},
    {sdo_abort::value_too_high, "value of parameter written too high"},
    {sdo_abort::value_too_low, "value of parameter written too low"},
    {sdo_abort::max_less_than_min, "maximum value is less than minimum value"},
    {sdo_abort::resource_not_available, "resource not available: SDO connection"},
    {sdo_abort::general_error, "general error"},
    {sdo_abort::cannot_store, "data cannot be transferred or stored to the application"},
    {sdo_abort::cannot_store_local_control,
     "data cannot be transferred or stored to the application because of local control"},
    {sdo_abort::cannot_store_device_state,
     "data cannot be transferred or stored to the application because of the present device state"},
    {sdo_abort::no_object_dictionary, "object dictionary dynamic generation failed or no object dictionary present"},
    {sdo_abort::no_data_available, "no data available"},
}};

}  // namespace

std::string_view sdo_abort_meaning(std::uint32_t code) {
  for (const auto& [c, meaning] : kMeanings) {
    if (c == code) return meaning;
  }
  return "unknown abort code";
}

}  // namespace lb::canopen
