#include "dds/security_proof.hpp"

#include <fastdds/rtps/common/SerializedPayload.h>
#include <fastdds/dds/log/Log.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastrtps/utils/fixed_size_string.hpp>

#include <cstdio>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "dds/security_policy.hpp"

namespace lb::ddsl {
namespace {

namespace fdds = eprosima::fastdds::dds;

// The smallest type a probe writer can be created with; nothing is ever written.
class ProbeType : public fdds::TopicDataType {
 public:
  ProbeType() {
    setName("linebridge::AccessControlProbe");
    m_typeSize = 4 + 4;  // encapsulation + one uint32
    m_isGetKeyDefined = false;
  }
  bool serialize(void*, eprosima::fastrtps::rtps::SerializedPayload_t*) override { return false; }
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t*, void*) override { return false; }
  std::function<uint32_t()> getSerializedSizeProvider(void*) override {
    return [] { return 8U; };
  }
  void* createData() override { return nullptr; }
  void deleteData(void*) override {}
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) override { return false; }
};

std::string property(const fdds::DomainParticipant& p, const std::string& name) {
  for (const auto& prop : p.get_qos().properties().properties()) {
    if (prop.name() == name) return prop.value();
  }
  return "(not set)";
}

std::string guid_prefix_text(const fdds::DomainParticipant& p) {
  const auto& v = p.guid().guidPrefix.value;
  char buf[40];
  std::snprintf(buf, sizeof buf, "%02x.%02x.%02x.%02x", v[0], v[1], v[2], v[3]);
  return buf;
}

// Fast DDS logs the probe writer's refusal, the expected outcome, as five "SECURITY Error" lines:
// every secured process would start with them as if something were wrong. Fast DDS's logger is
// the library's own process-wide one; its error-string filter drops them while the probe runs and
// is cleared after (a filter that matches everything), once the log queue has been written out.
class QuietProbeLog {
 public:
  QuietProbeLog() {
    fdds::Log::SetErrorStringFilter(
        std::regex("^(?![\\s\\S]*access_control_probe)(?!Problem creating associated Writer)"));
  }
  ~QuietProbeLog() {
    fdds::Log::Flush();
    fdds::Log::SetErrorStringFilter(std::regex(""));
  }
  QuietProbeLog(const QuietProbeLog&) = delete;
  QuietProbeLog& operator=(const QuietProbeLog&) = delete;
};

// True when a writer on the probe topic could be created (then deleted at once).
bool probe_writer_created(fdds::DomainParticipant& p, std::string& why_not_tested) {
  fdds::TypeSupport type(std::make_unique<ProbeType>().release());  // TypeSupport owns it by API design
  if (type.register_type(&p) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    why_not_tested = "cannot register the probe type";
    return false;
  }
  fdds::Topic* topic = p.create_topic(std::string(kAccessProbeTopic), type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Publisher* pub = p.create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  if (topic == nullptr || pub == nullptr) {
    why_not_tested = "cannot create the probe topic or publisher";
    if (pub != nullptr) p.delete_publisher(pub);
    if (topic != nullptr) p.delete_topic(topic);
    return false;
  }
  fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
  qos.data_sharing().off();
  fdds::DataWriter* w = nullptr;
  {
    QuietProbeLog quiet;
    w = pub->create_datawriter(topic, qos);
  }
  const bool created = w != nullptr;
  if (w != nullptr) pub->delete_datawriter(w);
  p.delete_publisher(pub);
  p.delete_topic(topic);
  p.unregister_type(type.get_type_name());
  return created;
}

}  // namespace

Result<void> prove_security_active(fdds::DomainParticipant& p) {
  std::vector<std::string> missing;
  if ((p.guid().guidPrefix.value[0] & 0x80) == 0) {
    missing.push_back(
        "authentication is not in force: the participant's GUID prefix " + guid_prefix_text(p) +
        " was not derived from a certificate (dds.sec.auth.plugin = " + property(p, "dds.sec.auth.plugin") +
        "; Fast DDS knows only builtin.PKI-DH and ignores anything else without a word)");
  }
  std::string why_not_tested;
  if (probe_writer_created(p, why_not_tested)) {
    missing.push_back(
        "access control is not in force: a writer on '" + std::string(kAccessProbeTopic) +
        "', a topic no grant may allow, was created (dds.sec.access.plugin = " + property(p, "dds.sec.access.plugin") +
        "; Fast DDS knows only builtin.Access-Permissions; or the permissions allow every topic)");
  } else if (!why_not_tested.empty()) {
    missing.push_back("access control could not be tested: " + why_not_tested);
  }
  if (const auto crypto = property(p, "dds.sec.crypto.plugin"); crypto != "builtin.AES-GCM-GMAC") {
    missing.push_back("encryption is not in force: dds.sec.crypto.plugin = " + crypto +
                      " (Fast DDS knows only builtin.AES-GCM-GMAC and sends in clear without it)");
  }
  if (missing.empty()) return {};
  std::string text = "DDS security is configured but not in force, refusing to run:";
  for (const auto& m : missing) text += "\n  " + m;
  return make_error(text);
}

}  // namespace lb::ddsl
