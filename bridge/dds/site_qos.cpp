#include "dds/site_qos.hpp"

#include <fastrtps/attributes/PublisherAttributes.h>
#include <fastrtps/attributes/SubscriberAttributes.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>

namespace lb::ddsl {
namespace {

namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::PublisherAttributes;
using eprosima::fastrtps::SubscriberAttributes;
using eprosima::fastrtps::xmlparser::XMLP_ret;
using eprosima::fastrtps::xmlparser::XMLProfileManager;

template <class T>
bool same(const T& a, const T& b) {
  return a == b;
}
// Fast DDS's own operator== memcmp()s the partitions' buffers, which are null while empty:
// undefined behaviour (UBSan reports it). The names say the same.
bool same(const fdds::PartitionQosPolicy& a, const fdds::PartitionQosPolicy& b) { return a.names() == b.names(); }

// Copies a policy the profile set (differs from Fast DDS's default) into the bridge's QoS.
template <class T>
void take(const T& site, const T& pristine, T& ours) {
  if (!same(site, pristine)) ours = site;
}

// A contract policy the profile set: reported, never applied.
template <class T>
void refuse(const T& site, const T& pristine, const std::string& topic, const char* what,
            std::vector<std::string>& notes) {
  if (!same(site, pristine))
    notes.push_back(topic + ": " + what + " is the DDS contract's: the site profile's is not applied");
}

template <class Attributes>
void refuse_contract(const Attributes& site, const std::string& topic, std::vector<std::string>& notes) {
  const Attributes pristine;
  refuse(site.qos.m_reliability.kind, pristine.qos.m_reliability.kind, topic, "reliability", notes);
  refuse(site.qos.m_durability.kind, pristine.qos.m_durability.kind, topic, "durability", notes);
  refuse(site.topic.historyQos, pristine.topic.historyQos, topic, "history", notes);
  refuse(site.topic.resourceLimitsQos, pristine.topic.resourceLimitsQos, topic, "resource limits", notes);
  refuse(site.qos.m_ownership, pristine.qos.m_ownership, topic, "ownership", notes);
  refuse(site.qos.m_partition, pristine.qos.m_partition, topic, "partition", notes);
  refuse(site.qos.m_destinationOrder, pristine.qos.m_destinationOrder, topic, "destination order", notes);
}

// What writers and readers share that a site may set.
template <class Attributes, class Qos>
void take_timing(const Attributes& site, Qos& qos) {
  const Attributes pristine;
  take(site.qos.m_deadline, pristine.qos.m_deadline, qos.deadline());
  take(site.qos.m_latencyBudget, pristine.qos.m_latencyBudget, qos.latency_budget());
  take(site.qos.m_liveliness, pristine.qos.m_liveliness, qos.liveliness());
  take(site.qos.m_userData, pristine.qos.m_userData, qos.user_data());
  take(site.historyMemoryPolicy, pristine.historyMemoryPolicy, qos.endpoint().history_memory_policy);
}

void merge(const PublisherAttributes& site, const std::string& topic, fdds::DataWriterQos& qos,
           std::vector<std::string>& notes) {
  const PublisherAttributes pristine;
  take_timing(site, qos);
  take(site.qos.m_lifespan, pristine.qos.m_lifespan, qos.lifespan());
  take(site.qos.m_publishMode, pristine.qos.m_publishMode, qos.publish_mode());
  take(site.times, pristine.times, qos.reliable_writer_qos().times);
  refuse_contract(site, topic, notes);
  refuse(site.qos.m_disablePositiveACKs, pristine.qos.m_disablePositiveACKs, topic, "disable_positive_acks", notes);
}

void merge(const SubscriberAttributes& site, const std::string& topic, fdds::DataReaderQos& qos,
           std::vector<std::string>& notes) {
  const SubscriberAttributes pristine;
  take_timing(site, qos);
  take(site.times, pristine.times, qos.reliable_reader_qos().times);
  refuse_contract(site, topic, notes);
  // A time-based filter would drop set values and requests.
  refuse(site.qos.m_timeBasedFilter, pristine.qos.m_timeBasedFilter, topic, "time_based_filter", notes);
}

}  // namespace

void apply_site_qos(const std::string& topic, fdds::DataWriterQos& qos, std::vector<std::string>& notes) {
  PublisherAttributes site;
  XMLProfileManager::getDefaultPublisherAttributes(site);
  merge(site, "default data_writer profile", qos, notes);
  if (XMLProfileManager::fillPublisherAttributes(topic, site, false) == XMLP_ret::XML_OK)
    merge(site, topic, qos, notes);
}

void apply_site_qos(const std::string& topic, fdds::DataReaderQos& qos, std::vector<std::string>& notes) {
  SubscriberAttributes site;
  XMLProfileManager::getDefaultSubscriberAttributes(site);
  merge(site, "default data_reader profile", qos, notes);
  if (XMLProfileManager::fillSubscriberAttributes(topic, site, false) == XMLP_ret::XML_OK)
    merge(site, topic, qos, notes);
}

}  // namespace lb::ddsl
