#include "dds/participant.hpp"

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include <chrono>

namespace lb::ddsl {
namespace {

using eprosima::fastrtps::rtps::IPLocator;
using eprosima::fastrtps::rtps::Locator_t;

// Reliable writers announce new data at this period; Fast DDS's 3 s default makes late joiners
// and lost-packet recovery slow for an HMI.
const eprosima::fastrtps::Duration_t kHeartbeatPeriod{0, 100'000'000};

// How many unacknowledged samples a keep-all (event) topic holds per endpoint before a writer blocks.
constexpr int kKeepAllLimit = 1000;

fdds::DomainParticipantQos participant_qos(const ParticipantOptions& options) {
  fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
  qos.name(options.name);
  // Short-lived participants (the CLI, HMI tools) come and go: announce often enough that a
  // missed initial announcement costs a second, not Fast DDS's default three, and forget a
  // participant that went away within ten seconds rather than twenty.
  auto& discovery = qos.wire_protocol().builtin.discovery_config;
  discovery.leaseDuration = eprosima::fastrtps::Duration_t(10, 0);
  discovery.leaseDuration_announcementperiod = eprosima::fastrtps::Duration_t(1, 0);
  discovery.initial_announcements.count = 5;
  discovery.initial_announcements.period = eprosima::fastrtps::Duration_t(0, 50'000'000);
  if (options.localhost_only) {
    qos.transport().use_builtin_transports = false;
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    udp->interfaceWhiteList.emplace_back("127.0.0.1");
    qos.transport().user_transports.push_back(udp);
    qos.transport().user_transports.push_back(std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>());
    Locator_t peer;
    peer.kind = LOCATOR_KIND_UDPv4;
    IPLocator::setIPv4(peer, 127, 0, 0, 1);
    qos.wire_protocol().builtin.initialPeersList.push_back(peer);
  }
  return qos;
}

// What each kind means; writers and readers of a kind get the same, so they always match.
struct KindQos {
  fdds::DurabilityQosPolicyKind durability;
  fdds::HistoryQosPolicyKind history;
  int depth;
};

KindQos kind_qos(QosKind kind) {
  switch (kind) {
    case QosKind::state: return {fdds::TRANSIENT_LOCAL_DURABILITY_QOS, fdds::KEEP_LAST_HISTORY_QOS, 1};
    case QosKind::command: return {fdds::VOLATILE_DURABILITY_QOS, fdds::KEEP_LAST_HISTORY_QOS, 16};
    case QosKind::event: return {fdds::VOLATILE_DURABILITY_QOS, fdds::KEEP_ALL_HISTORY_QOS, 1};
    case QosKind::reply: return {fdds::TRANSIENT_LOCAL_DURABILITY_QOS, fdds::KEEP_LAST_HISTORY_QOS, 16};
  }
  return {fdds::VOLATILE_DURABILITY_QOS, fdds::KEEP_LAST_HISTORY_QOS, 1};
}

// Every topic is unkeyed (one instance), so the history needs no more room than its depth, and it
// starts with room for one sample and grows on demand. Fast DDS's defaults (10 instances, 100
// samples preallocated at the type's largest size, a data-sharing pool per endpoint sized for
// 5000 samples) cost over 100 KiB per endpoint, and a bridge has thousands of endpoints on a full line.
template <class Qos>
void set_history(Qos& qos, fdds::HistoryQosPolicyKind kind, int depth) {
  qos.history().kind = kind;
  qos.history().depth = depth;
  auto& limits = qos.resource_limits();
  limits.max_instances = 1;
  if (kind == fdds::KEEP_LAST_HISTORY_QOS) {
    limits.max_samples = depth;
    limits.max_samples_per_instance = depth;
    limits.allocated_samples = 1;
  } else {
    // Keep-all: the bound a slow reader can hold back, growing from a few on demand.
    limits.max_samples = kKeepAllLimit;
    limits.max_samples_per_instance = kKeepAllLimit;
    limits.allocated_samples = 1;
  }
  // The shared-memory transport still carries data between processes on one host; data sharing
  // would add a fixed-size pool per endpoint on top of it.
  qos.data_sharing().off();
}

template <class Qos>
Qos with_kind(Qos qos, QosKind kind) {
  const KindQos k = kind_qos(kind);
  qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = k.durability;
  set_history(qos, k.history, k.depth);
  return qos;
}

fdds::DataWriterQos writer_qos(QosKind kind) {
  auto qos = with_kind(fdds::DATAWRITER_QOS_DEFAULT, kind);
  qos.reliable_writer_qos().times.heartbeatPeriod = kHeartbeatPeriod;
  return qos;
}

fdds::DataReaderQos reader_qos(QosKind kind) { return with_kind(fdds::DATAREADER_QOS_DEFAULT, kind); }

}  // namespace

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

Result<std::unique_ptr<Participant>> Participant::create(const ParticipantOptions& options) {
  auto p = std::make_unique<Participant>(Key{});
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  p->participant_ = factory->create_participant(options.domain, participant_qos(options));
  if (p->participant_ == nullptr) return make_error("cannot create DDS participant on domain " + std::to_string(options.domain));
  p->publisher_ = p->participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  p->subscriber_ = p->participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (p->publisher_ == nullptr || p->subscriber_ == nullptr) return make_error("cannot create DDS publisher/subscriber");
  return p;
}

Participant::~Participant() {
  if (participant_ == nullptr) return;
  // Stops every listener before they are freed (members are destroyed after this body).
  participant_->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

Result<fdds::Topic*> Participant::topic_for_type(const std::string& name, fdds::TypeSupport type) {
  std::lock_guard lock(mutex_);
  if (auto it = topics_.find(name); it != topics_.end()) {
    if (it->second->get_type_name() != type.get_type_name()) {
      return make_error("topic " + name + " is already used with type " + it->second->get_type_name());
    }
    return it->second;
  }
  type.register_type(participant_);  // registering a type twice is harmless
  fdds::Topic* topic = participant_->create_topic(name, type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  if (topic == nullptr) return make_error("cannot create DDS topic " + name);
  topics_.emplace(name, topic);
  return topic;
}

fdds::DataWriter* Participant::create_writer(fdds::Topic* topic, QosKind kind) {
  auto* w = publisher_->create_datawriter(topic, writer_qos(kind));
  if (w != nullptr) {
    std::lock_guard lock(mutex_);
    writers_[topic->get_name()].push_back(w);
  }
  return w;
}

fdds::DataReader* Participant::create_reader(fdds::Topic* topic, QosKind kind, int keep_last,
                                             fdds::DataReaderListener* listener) {
  auto qos = reader_qos(kind);
  if (keep_last > 0 && qos.history().kind == fdds::KEEP_LAST_HISTORY_QOS) set_history(qos, fdds::KEEP_LAST_HISTORY_QOS, keep_last);
  auto* r = subscriber_->create_datareader(topic, qos, listener);
  if (r != nullptr) {
    std::lock_guard lock(mutex_);
    readers_[topic->get_name()].push_back(r);
  }
  return r;
}

void Participant::remove_reader(fdds::DataReader* reader) {
  {
    std::lock_guard lock(mutex_);
    for (auto& [name, readers] : readers_) std::erase(readers, reader);
  }
  // Returns once no listener call is running on it, so its listener can be freed after.
  subscriber_->delete_datareader(reader);
}

void Participant::remove_writer(fdds::DataWriter* writer) {
  {
    std::lock_guard lock(mutex_);
    for (auto& [name, writers] : writers_) std::erase(writers, writer);
  }
  publisher_->delete_datawriter(writer);
}

int Participant::matched_readers(const std::string& topic) const {
  std::lock_guard lock(mutex_);
  int n = 0;
  if (auto it = writers_.find(topic); it != writers_.end()) {
    for (auto* w : it->second) {
      fdds::PublicationMatchedStatus s;
      w->get_publication_matched_status(s);
      n += s.current_count;
    }
  }
  return n;
}

int Participant::matched_writers(const std::string& topic) const {
  std::lock_guard lock(mutex_);
  int n = 0;
  if (auto it = readers_.find(topic); it != readers_.end()) {
    for (auto* r : it->second) {
      fdds::SubscriptionMatchedStatus s;
      r->get_subscription_matched_status(s);
      n += s.current_count;
    }
  }
  return n;
}

}  // namespace lb::ddsl
