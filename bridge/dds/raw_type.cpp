#include "dds/raw_type.hpp"

#include <cstring>
#include <memory>

namespace lb::ddsl {

RawType::RawType(const std::string& name, std::uint32_t max_size) {
  setName(name.c_str());
  m_typeSize = max_size;
  m_isGetKeyDefined = false;
}

bool RawType::serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) {
  const auto& cdr = static_cast<RawSample*>(data)->cdr;
  if (cdr.size() < 4 || cdr.size() > payload->max_size) return false;
  std::memcpy(payload->data, cdr.data(), cdr.size());
  payload->length = static_cast<std::uint32_t>(cdr.size());
  // The encapsulation header's second byte: 0 big-endian, 1 little-endian CDR.
  payload->encapsulation = cdr[1] == 0 ? CDR_BE : CDR_LE;
  return true;
}

bool RawType::deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) {
  auto& cdr = static_cast<RawSample*>(data)->cdr;
  cdr.assign(payload->data, payload->data + payload->length);
  return true;
}

std::function<std::uint32_t()> RawType::getSerializedSizeProvider(void* data) {
  const auto size = static_cast<std::uint32_t>(static_cast<RawSample*>(data)->cdr.size());
  return [size] { return size; };
}

// Fast DDS owns what createData returns and hands it back to deleteData (its API's contract).
void* RawType::createData() { return std::make_unique<RawSample>().release(); }
void RawType::deleteData(void* data) { std::unique_ptr<RawSample>{static_cast<RawSample*>(data)}; }

bool RawType::getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) { return false; }

}  // namespace lb::ddsl
