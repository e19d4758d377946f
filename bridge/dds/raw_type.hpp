#pragma once
// A DDS type known only by its name and largest size, whose samples are their CDR bytes: the DDS
// process publishes and reads the contract's types without linking them (the bus process
// serializes, dds/cdr.hpp). On the wire a raw sample is byte for byte the typed one, so peers
// cannot tell (no type object is registered: fastddsgen runs without -typeobject). No type of
// the contract has a key.

#include <fastdds/dds/topic/TopicDataType.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace lb::ddsl {

struct RawSample {
  std::vector<std::uint8_t> cdr;  // encapsulation header included
};

class RawType : public eprosima::fastdds::dds::TopicDataType {
 public:
  RawType(const std::string& name, std::uint32_t max_size);
  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override;
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override;
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override;
  void* createData() override;
  void deleteData(void* data) override;
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* handle, bool force_md5) override;
};

}  // namespace lb::ddsl
