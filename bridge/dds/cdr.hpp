#pragma once
// A sample of the contract as its CDR serialization (encapsulation header included), exactly the
// bytes Fast DDS puts on the wire: what the channel between the bus and DDS processes carries.
// Fast CDR only: the generated types serialize themselves without the RTPS library.

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>

#include <cstdint>
#include <span>
#include <vector>

namespace lb::ddsl {

template <class Sample>
std::vector<std::uint8_t> to_cdr(const Sample& sample) {
  std::vector<std::uint8_t> out(Sample::getCdrSerializedSize(sample) + 4);
  eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(out.data()), out.size());
  eprosima::fastcdr::Cdr ser(buffer, eprosima::fastcdr::Cdr::DEFAULT_ENDIAN, eprosima::fastcdr::Cdr::DDS_CDR);
  ser.serialize_encapsulation();
  sample.serialize(ser);
  out.resize(ser.getSerializedDataLength());
  return out;
}

// False when the bytes are not a sample of this type (truncated, or a length beyond them).
template <class Sample>
bool from_cdr(std::span<const std::uint8_t> bytes, Sample& sample) {
  // Fast CDR reads through a non-const buffer; it does not write to it when deserializing.
  eprosima::fastcdr::FastBuffer buffer(const_cast<char*>(reinterpret_cast<const char*>(bytes.data())), bytes.size());
  eprosima::fastcdr::Cdr deser(buffer, eprosima::fastcdr::Cdr::DEFAULT_ENDIAN, eprosima::fastcdr::Cdr::DDS_CDR);
  try {
    deser.read_encapsulation();
    sample.deserialize(deser);
  } catch (const eprosima::fastcdr::exception::Exception&) {
    return false;
  }
  return true;
}

}  // namespace lb::ddsl
