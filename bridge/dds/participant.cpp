#include "dds/participant.hpp"
#include "dds/raw_type.hpp"

#include <spdlog/spdlog.h>

#include <fastdds/rtps/attributes/ServerAttributes.h>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <sstream>

#include "dds/gate_transport.hpp"
#include "dds/security_proof.hpp"
#include "dds/site_profiles.hpp"
#include "dds/site_qos.hpp"

namespace lb::ddsl {
namespace {

using eprosima::fastrtps::rtps::IPLocator;
using eprosima::fastrtps::rtps::Locator_t;

// Reliable writers announce new data at this period; Fast DDS's 3 s default makes late joiners
// and lost-packet recovery slow for an HMI.
const eprosima::fastrtps::Duration_t kHeartbeatPeriod{0, 100'000'000};

// Events (cuts, emergencies) a reader that falls behind can still catch up on. Keep-last, not
// keep-all: a keep-all writer blocks when a reader stops acknowledging, and the bridge writes from
// its bus loop, so one frozen HMI would stop SYNC for the whole bus (measured: 58 SYNCs instead of
// 200 in 4 s of an EMCY burst). A reader more than this many behind loses the oldest.
constexpr int kEventDepth = 1000;

// Every transport of the participant but shared memory behind the gate (gate_transport.hpp).
// Shared memory stays as it is: only processes of this machine (and its user) reach it, and Fast
// DDS recognises that transport by its descriptor's type.
void gate_transports(fdds::DomainParticipantQos& qos, const std::shared_ptr<DiscoveryGate>& gate,
                     std::vector<std::string>& notes) {
  auto& transports = qos.transport();
  if (transports.use_builtin_transports) {
    // A site profile that adds transports to Fast DDS's built-in ones: UDPv4 is made explicitly,
    // so that it sits behind the gate too (Fast DDS's built-in shared memory is left out, as
    // dds.shared_memory: false does for the bridge's own transports).
    transports.use_builtin_transports = false;
    transports.user_transports.push_back(std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>());
    notes.emplace_back(
        "the site profile's built-in transports are replaced by UDPv4 behind the discovery gate (set dds.shared_memory "
        "for shared memory)");
  }
  for (auto& t : transports.user_transports) {
    if (std::dynamic_pointer_cast<eprosima::fastdds::rtps::SharedMemTransportDescriptor>(t)) continue;
    if (std::dynamic_pointer_cast<GateTransportDescriptor>(t)) continue;
    t = std::make_shared<GateTransportDescriptor>(t, gate);
  }
}

// The site's participant QoS (XML profiles) with the bridge's choices where the site says nothing.
Result<fdds::DomainParticipantQos> base_qos(const ParticipantOptions& options, std::vector<std::string>& notes,
                                            const std::shared_ptr<DiscoveryGate>& gate) {
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
  auto site = load_site_profiles(options.profiles_file);
  if (!site) return site.error();
  const std::string profile = !options.participant_profile.empty() ? options.participant_profile
                              : site->default_participant          ? *site->default_participant
                                                                   : std::string();
  if (!profile.empty()) {
    if (factory->get_participant_qos_from_profile(profile, qos) !=
        eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      return make_error("no participant profile '" + profile + "' in the DDS profiles files");
    }
  } else {
    factory->get_default_participant_qos(qos);  // FASTRTPS_DEFAULT_PROFILES_FILE's default, or Fast DDS's
  }
  const fdds::DomainParticipantQos pristine = fdds::PARTICIPANT_QOS_DEFAULT;
  if (qos.name() == pristine.name()) qos.name(options.name);
  // Announce every 250 ms, not every 3 s (Fast DDS's default). Fast DDS 2.9.1 sends a new
  // participant's first announcement before it reads its sockets (RTPSParticipantImpl::enable), so
  // the direct answer of a participant already running can arrive unread (about one start in
  // fifteen on one machine, measured with a packet trace); the newcomer then learns of it only from
  // its next periodic announcement: this period is how late a restarted bridge can reach a running
  // client that uses this code (the CLI), and how late a new client can reach the bridge. Forget a
  // participant that went away within ten seconds rather than twenty. A site's own values win.
  auto& discovery = qos.wire_protocol().builtin.discovery_config;
  const auto& fast = pristine.wire_protocol().builtin.discovery_config;
  if (discovery.leaseDuration == fast.leaseDuration) discovery.leaseDuration = eprosima::fastrtps::Duration_t(10, 0);
  if (discovery.leaseDuration_announcementperiod == fast.leaseDuration_announcementperiod) {
    discovery.leaseDuration_announcementperiod = eprosima::fastrtps::Duration_t(0, 250'000'000);
  }
  if (discovery.initial_announcements == fast.initial_announcements) {
    discovery.initial_announcements.count = 5;
    discovery.initial_announcements.period = eprosima::fastrtps::Duration_t(0, 50'000'000);
  }
  // Transports. UDP only unless the line asks for shared memory: Fast DDS 2.9's shared-memory
  // transport carries nothing between processes of different users (measured: a bridge running as
  // its service user and a CLI run by root or an operator on the same machine never saw each
  // other, with no error on either side), while UDP on loopback always works (at 36-62 % more CPU
  // per write, BENCHMARKS.md).
  const auto udp_on = [&](const char* address) {
    qos.transport().use_builtin_transports = false;
    qos.transport().user_transports.clear();
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    if (address != nullptr) udp->interfaceWhiteList.emplace_back(address);
    qos.transport().user_transports.push_back(udp);
    if (options.shared_memory) {
      qos.transport().user_transports.push_back(
          std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>());
    }
  };
  const bool site_transports = !(qos.transport() == pristine.transport());
  if (options.localhost_only) {
    // localhost_only keeps DDS on this machine whatever a profile says.
    if (site_transports || !qos.wire_protocol().builtin.initialPeersList.empty()) {
      notes.emplace_back("dds.localhost_only is true: the site profile's transports and initial peers are not used");
    }
    udp_on("127.0.0.1");
    qos.wire_protocol().builtin.initialPeersList.clear();
    if (options.discovery_servers.empty()) {
      Locator_t peer;
      peer.kind = LOCATOR_KIND_UDPv4;
      IPLocator::setIPv4(peer, 127, 0, 0, 1);
      qos.wire_protocol().builtin.initialPeersList.push_back(peer);
    }
  } else if (!site_transports) {
    udp_on(nullptr);  // every interface, as Fast DDS's built-in UDP transport
  } else if (options.shared_memory) {
    notes.emplace_back("dds.shared_memory: the site profile's transports are used as they are");
  }
  if (!options.discovery_servers.empty()) {
    if (discovery.discoveryProtocol != eprosima::fastrtps::rtps::DiscoveryProtocol_t::SIMPLE) {
      notes.emplace_back("dds.discovery_servers replaces the site profile's discovery protocol");
    }
    discovery.discoveryProtocol = options.see_all_endpoints
                                      ? eprosima::fastrtps::rtps::DiscoveryProtocol_t::SUPER_CLIENT
                                      : eprosima::fastrtps::rtps::DiscoveryProtocol_t::CLIENT;
    discovery.m_DiscoveryServers.clear();
    for (const auto& server : options.discovery_servers) {
      eprosima::fastdds::rtps::RemoteServerAttributes remote;
      eprosima::fastdds::rtps::get_server_client_default_guidPrefix(server.id, remote.guidPrefix);
      Locator_t locator;
      locator.kind = LOCATOR_KIND_UDPv4;
      IPLocator::setIPv4(locator, server.address);
      IPLocator::setPhysicalPort(locator, server.port);
      remote.metatrafficUnicastLocatorList.push_back(locator);
      discovery.m_DiscoveryServers.push_back(remote);
    }
  }
  if (gate) {
    if (discovery.discoveryProtocol == eprosima::fastrtps::rtps::DiscoveryProtocol_t::SIMPLE) {
      gate_transports(qos, gate, notes);
    } else if (options.discovery_servers.empty()) {
      notes.emplace_back(
          "the site profile's discovery protocol is not simple discovery: no discovery gate (a discovery server's "
          "client takes announcements from its servers only)");
    }
  }
  return qos;
}

// Fast DDS takes file URIs only ("file://" + path; a bare path is refused).
std::string file_uri(const std::string& path) { return "file://" + std::filesystem::absolute(path).string(); }

void add_security(fdds::DomainParticipantQos& qos, const SecurityFiles& files) {
  auto& props = qos.properties().properties();
  const auto set = [&props](const std::string& name, const std::string& value) {
    for (auto& p : props) {
      if (p.name() == name) return void(p.value() = value);
    }
    props.emplace_back(name, value);
  };
  set("dds.sec.auth.plugin", "builtin.PKI-DH");
  set("dds.sec.auth.builtin.PKI-DH.identity_ca", file_uri(files.identity_ca));
  set("dds.sec.auth.builtin.PKI-DH.identity_certificate", file_uri(files.certificate));
  set("dds.sec.auth.builtin.PKI-DH.private_key", file_uri(files.private_key));
  set("dds.sec.access.plugin", "builtin.Access-Permissions");
  set("dds.sec.access.builtin.Access-Permissions.permissions_ca", file_uri(files.permissions_ca));
  set("dds.sec.access.builtin.Access-Permissions.governance", file_uri(files.governance));
  set("dds.sec.access.builtin.Access-Permissions.permissions", file_uri(files.permissions));
  if (!files.identity_crl.empty()) set("dds.sec.auth.builtin.PKI-DH.identity_crl", file_uri(files.identity_crl));
  set("dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC");
  for (const auto& [name, value] : files.properties) set(name, value);
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
    case QosKind::event: return {fdds::VOLATILE_DURABILITY_QOS, fdds::KEEP_LAST_HISTORY_QOS, kEventDepth};
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
  limits.max_samples = depth;
  limits.max_samples_per_instance = depth;
  limits.allocated_samples = 1;
  // The transports (UDP, shared memory where a line asks for it) carry data between processes; data sharing
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

// The bridge's QoS of a kind, then what the site's profiles may change of it (site_qos.hpp), then
// the kind again: the contract's policies are never the site's.
// Payloads allocated at the size of the samples an endpoint really has, and reused, instead of
// preallocated at its type's largest serialized size, two per writer (DeviceInfo 64 KiB,
// Diagnostics 3 MiB): those pools were 45 MB of the DDS process's 84 MB heap at 8 x 30 devices.
// A site's profile may choose another policy (site_qos.hpp).
constexpr auto kPayloadMemory = eprosima::fastrtps::rtps::DYNAMIC_REUSABLE_MEMORY_MODE;

fdds::DataWriterQos writer_qos(const std::string& topic, QosKind kind, std::vector<std::string>& notes) {
  auto qos = with_kind(fdds::DATAWRITER_QOS_DEFAULT, kind);
  qos.reliable_writer_qos().times.heartbeatPeriod = kHeartbeatPeriod;
  qos.endpoint().history_memory_policy = kPayloadMemory;
  apply_site_qos(topic, qos, notes);
  return with_kind(qos, kind);
}

fdds::DataReaderQos reader_qos(const std::string& topic, QosKind kind, std::vector<std::string>& notes) {
  auto qos = with_kind(fdds::DATAREADER_QOS_DEFAULT, kind);
  qos.endpoint().history_memory_policy = kPayloadMemory;
  apply_site_qos(topic, qos, notes);
  return with_kind(qos, kind);
}

// "reliable, transient-local[, deadline 2 s]": what a discovered endpoint announced.
template <class Qos>
std::string qos_text(const Qos& q) {
  std::string out = std::string(q.m_reliability.kind == fdds::RELIABLE_RELIABILITY_QOS ? "reliable" : "best-effort") +
                    ", " + (q.m_durability.kind == fdds::VOLATILE_DURABILITY_QOS ? "volatile" : "transient-local");
  if (q.m_deadline.period != eprosima::fastrtps::c_TimeInfinite) {
    std::ostringstream s;
    s << ", deadline " << q.m_deadline.period.to_ns() / 1e9 << " s";
    out += s.str();
  }
  return out;
}
std::string partitions_text(const fdds::PartitionQosPolicy& p) {
  std::string out;
  for (const auto& name : p.getNames()) out += (out.empty() ? "" : ",") + name;
  return out;
}
template <class T>
std::string guid_text(const T& guid) {
  std::ostringstream s;
  s << guid;
  return s.str();
}

}  // namespace

struct RemoteTally {
  std::atomic<int> known{0};
  std::atomic<std::uint64_t> refused{0}, departed{0};
};

namespace {

GuidPrefix prefix_of(const eprosima::fastrtps::rtps::GuidPrefix_t& p) {
  GuidPrefix out{};
  std::copy(std::begin(p.value), std::end(p.value), out.begin());
  return out;
}

// Discovery callbacks of a participant: the remote participants' tally, the discovery gate (which
// participants authenticated, failed to, or left), the secured bridge's partition bookkeeping (it
// must run before matching), then a tool's observer.
class Listener : public fdds::DomainParticipantListener {
 public:
  Listener(RemoteTally& tally, WriterPartitions* partitions, DiscoveryObserver observer, DiscoveryGate* gate)
      : tally_(tally), partitions_(partitions), observer_(std::move(observer)), gate_(gate) {}

  void on_participant_discovery(fdds::DomainParticipant*,
                                eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override {
    using S = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
    const bool removed = info.status == S::REMOVED_PARTICIPANT || info.status == S::DROPPED_PARTICIPANT;
    if (info.status == S::DISCOVERED_PARTICIPANT) ++tally_.known;
    if (removed) {
      --tally_.known;
      ++tally_.departed;
      if (gate_ != nullptr) gate_->departed(prefix_of(info.info.m_guid.guidPrefix));
    }
    if (!observer_) return;
    observer_({DiscoveryEvent::Kind::participant,
               removed,
               guid_text(info.info.m_guid.guidPrefix),
               info.info.m_participantName.to_string(),
               {},
               {},
               {}});
  }
  void onParticipantAuthentication(fdds::DomainParticipant*,
                                   eprosima::fastrtps::rtps::ParticipantAuthenticationInfo&& info) override {
    using A = eprosima::fastrtps::rtps::ParticipantAuthenticationInfo;
    if (info.status == A::UNAUTHORIZED_PARTICIPANT) ++tally_.refused;
    if (gate_ == nullptr) return;
    const auto prefix = prefix_of(info.guid.guidPrefix);
    if (info.status == A::AUTHORIZED_PARTICIPANT) gate_->authenticated(prefix, DiscoveryGate::Clock::now());
    if (info.status == A::UNAUTHORIZED_PARTICIPANT) gate_->refused(prefix, DiscoveryGate::Clock::now());
  }
  void on_publisher_discovery(fdds::DomainParticipant* participant,
                              eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override {
    if (partitions_ != nullptr)
      partitions_->on_publisher_discovery(participant, eprosima::fastrtps::rtps::WriterDiscoveryInfo(info));
    if (!observer_) return;
    using S = eprosima::fastrtps::rtps::WriterDiscoveryInfo;
    observer_({DiscoveryEvent::Kind::writer, info.status == S::REMOVED_WRITER, guid_text(info.info.guid()),
               info.info.topicName().to_string(), info.info.typeName().to_string(), qos_text(info.info.m_qos),
               partitions_text(info.info.m_qos.m_partition)});
  }
  void on_subscriber_discovery(fdds::DomainParticipant*,
                               eprosima::fastrtps::rtps::ReaderDiscoveryInfo&& info) override {
    if (!observer_) return;
    using S = eprosima::fastrtps::rtps::ReaderDiscoveryInfo;
    observer_({DiscoveryEvent::Kind::reader, info.status == S::REMOVED_READER, guid_text(info.info.guid()),
               info.info.topicName().to_string(), info.info.typeName().to_string(), qos_text(info.info.m_qos),
               partitions_text(info.info.m_qos.m_partition)});
  }

 private:
  RemoteTally& tally_;
  WriterPartitions* partitions_;
  DiscoveryObserver observer_;
  DiscoveryGate* gate_;
};

}  // namespace

Result<fdds::DomainParticipantQos> participant_qos(const ParticipantOptions& options, std::vector<std::string>* notes,
                                                   const std::shared_ptr<DiscoveryGate>& gate) {
  std::vector<std::string> ignored;
  auto qos = base_qos(options, notes != nullptr ? *notes : ignored, gate);
  if (!qos) return qos.error();
  if (options.security) add_security(*qos, *options.security);
  // Fast DDS 2.9 announces the host name, the user and the process id in every participant's
  // discovery data (propagated properties), unencrypted before authentication: nothing a peer
  // needs, and a map of the plant for anyone who listens.
  std::erase_if(qos->properties().properties(), [](const eprosima::fastrtps::rtps::Property& p) {
    return p.name().rfind("fastdds.physical_data.", 0) == 0;
  });
  return qos;
}

std::string_view to_string(QosKind kind) {
  switch (kind) {
    case QosKind::state: return "reliable, transient-local, keep-last 1";
    case QosKind::command: return "reliable, volatile, keep-last 16";
    case QosKind::event: return "reliable, volatile, keep-last 1000";
    case QosKind::reply: return "reliable, transient-local, keep-last 16";
  }
  return "?";
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

Result<std::unique_ptr<Participant>> Participant::create(const ParticipantOptions& options) {
  auto p = create_checked(options);
  if (!p) return make_error(p.error().message);
  return std::move(*p);
}

Result<std::unique_ptr<Participant>, CreateError> Participant::create_checked(const ParticipantOptions& options) {
  auto p = std::make_unique<Participant>(Key{});
  if (options.security) {
    if (auto files = check_security_files(*options.security, options.domain); !files) {
      return CreateError{files.error().message, true};
    }
    for (auto& w : grant_warnings(*options.security, options.domain)) p->site_notes_.push_back(std::move(w));
    p->writer_partitions_ = std::make_unique<WriterPartitions>();
  }
  if (options.discovery_servers.empty()) {
    p->discovery_gate_ = std::make_shared<DiscoveryGate>(options.security ? DiscoveryGate::Proof::authentication
                                                                          : DiscoveryGate::Proof::traffic,
                                                         options.gate);
  }
  auto qos = participant_qos(options, &p->site_notes_, p->discovery_gate_);
  if (!qos) return CreateError{qos.error().message, true};
  // A site profile's discovery protocol may leave the gate out (its transports were not wrapped).
  if (qos->wire_protocol().builtin.discovery_config.discoveryProtocol !=
      eprosima::fastrtps::rtps::DiscoveryProtocol_t::SIMPLE)
    p->discovery_gate_.reset();
  p->remote_tally_ = std::make_shared<RemoteTally>();
  p->listener_ = std::make_unique<Listener>(*p->remote_tally_, p->writer_partitions_.get(), options.on_discovery,
                                            p->discovery_gate_.get());
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  p->participant_ = factory->create_participant(options.domain, *qos, p->listener_.get(), fdds::StatusMask::none());
  if (p->participant_ == nullptr) {
    if (!options.security)
      return CreateError{"cannot create DDS participant on domain " + std::to_string(options.domain)};
    return CreateError{"Fast DDS refused the secured participant on domain " + std::to_string(options.domain) +
                           " although its files passed linebridge's checks (see Fast DDS's messages above; a property "
                           "given in dds.security.properties?)",
                       true};
  }
  if (p->discovery_gate_) p->discovery_gate_->set_local(prefix_of(p->participant_->guid().guidPrefix));
  if (options.security) {
    if (auto proof = prove_security_active(*p->participant_); !proof) return CreateError{proof.error().message, true};
    p->secured_ = true;
  }
  p->publisher_ = p->participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  p->subscriber_ = p->participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (p->publisher_ == nullptr || p->subscriber_ == nullptr)
    return CreateError{"cannot create DDS publisher/subscriber"};
  return p;
}

Result<std::unique_ptr<Participant>, CreateError> Participant::plan(const ParticipantOptions& options) {
  auto p = std::make_unique<Participant>(Key{});
  p->planning_ = true;
  if (options.security) {
    if (auto files = check_security_files(*options.security, options.domain); !files) {
      return CreateError{files.error().message, true};
    }
    for (auto& w : grant_warnings(*options.security, options.domain)) p->site_notes_.push_back(std::move(w));
    p->secured_ = true;  // so the plan has the secured line's endpoints (requests in every partition)
  }
  auto qos = participant_qos(options, &p->site_notes_);
  if (!qos) return CreateError{qos.error().message, true};
  return p;
}

std::unique_ptr<Participant> Participant::over_channel(const ParticipantOptions& options, link::BusChannel& channel) {
  auto p = std::make_unique<Participant>(Key{});
  p->channel_ = &channel;
  p->incarnation_ = channel.incarnation();
  // The DDS process proves security is in force before it serves the channel; this side needs to
  // know only that the line is secured (line-wide requests are then taken by partition).
  p->secured_ = options.security.has_value();
  return p;
}

void Participant::heard_partitions(const eprosima::fastrtps::rtps::GUID_t& writer,
                                   const std::vector<std::string>& partitions) {
  std::lock_guard lock(mutex_);
  // Bounded: writers come and go with clients; a writer forgotten here is told again with its next sample.
  if (channel_partitions_.size() >= 1024) channel_partitions_.clear();
  channel_partitions_[writer] = partitions;
}

void Participant::undecodable(const std::string& topic) {
  static constexpr auto kEvery = std::chrono::seconds(10);
  std::lock_guard lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  if (now - last_undecodable_log_ >= kEvery) {
    last_undecodable_log_ = now;
    spdlog::warn("a sample on {} from the DDS process is not of its type: dropped", topic);
  }
}

void Participant::record_plan(PlannedEndpoint endpoint) {
  std::lock_guard lock(mutex_);
  // The QoS the site profiles would give it: what they set that is not applied becomes a note.
  if (endpoint.writer) {
    writer_qos(endpoint.topic, endpoint.kind, site_notes_);
  } else {
    reader_qos(endpoint.topic, endpoint.kind, site_notes_);
  }
  planned_.push_back(std::move(endpoint));
}

std::vector<std::string> Participant::site_notes() const {
  std::lock_guard lock(mutex_);
  std::vector<std::string> unique;
  for (const auto& n : site_notes_) {
    if (std::find(unique.begin(), unique.end(), n) == unique.end()) unique.push_back(n);
  }
  return unique;
}

RemoteCounts Participant::remote_counts() const {
  if (!remote_tally_) return {};
  return {remote_tally_->known.load(), remote_tally_->refused.load(), remote_tally_->departed.load()};
}

bool Participant::writer_in_partition(const eprosima::fastrtps::rtps::GUID_t& writer,
                                      std::string_view partition) const {
  if (channel_ != nullptr) {
    std::lock_guard lock(mutex_);
    const auto it = channel_partitions_.find(writer);
    return it != channel_partitions_.end() &&
           std::find(it->second.begin(), it->second.end(), partition) != it->second.end();
  }
  return writer_partitions_ != nullptr && writer_partitions_->contains(writer, partition);
}

Result<fdds::DataWriter*> Participant::raw_writer(const link::Declare& d) {
  auto t = topic_for_type(d.topic, fdds::TypeSupport(std::make_unique<RawType>(d.type, d.max_size).release()));
  if (!t) return t.error();
  auto* w = create_writer(*t, static_cast<QosKind>(d.qos_kind), d.partition);
  if (w == nullptr) {
    return make_error("cannot create DDS writer on " + d.topic +
                      (d.partition.empty() ? "" : " in partition '" + d.partition + "'") +
                      (secured_ ? " (do this identity's permissions grant it?)" : ""));
  }
  return w;
}

namespace {
class RawListener : public fdds::DataReaderListener {
 public:
  RawListener(Participant::RawCallback cb, const WriterPartitions* partitions, bool any_partition)
      : cb_(std::move(cb)), partitions_(partitions), any_partition_(any_partition) {}
  void on_data_available(fdds::DataReader* reader) override {
    RawSample sample;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&sample, &info) == eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::vector<std::string> in;
      if (any_partition_ && partitions_ != nullptr) in = partitions_->of(info.sample_identity.writer_guid());
      cb_(sample.cdr, info, std::move(in));
    }
  }

 private:
  Participant::RawCallback cb_;
  const WriterPartitions* partitions_;
  bool any_partition_;
};
}  // namespace

Result<void> Participant::subscribe_raw(const link::Declare& d, RawCallback callback) {
  auto t = topic_for_type(d.topic, fdds::TypeSupport(std::make_unique<RawType>(d.type, d.max_size).release()));
  if (!t) return t.error();
  auto listener = std::make_unique<RawListener>(std::move(callback), writer_partitions_.get(), d.any_partition);
  if (create_reader(*t, static_cast<QosKind>(d.qos_kind), d.keep_last, listener.get(), d.any_partition) == nullptr) {
    return make_error("cannot create DDS reader on " + d.topic);
  }
  std::lock_guard lock(mutex_);
  listeners_.push_back(std::move(listener));
  return {};
}

fdds::Publisher* Participant::publisher_in(const std::string& partition) {
  if (partition.empty()) return publisher_;
  std::lock_guard lock(mutex_);
  auto& pub = partition_publishers_[partition];
  if (pub == nullptr) {
    fdds::PublisherQos qos = fdds::PUBLISHER_QOS_DEFAULT;
    qos.partition().push_back(partition.c_str());
    pub = participant_->create_publisher(qos);
  }
  return pub;
}

fdds::Subscriber* Participant::any_partition_subscriber() {
  std::lock_guard lock(mutex_);
  if (any_partition_subscriber_ == nullptr) {
    fdds::SubscriberQos qos = fdds::SUBSCRIBER_QOS_DEFAULT;
    qos.partition().push_back("*");
    any_partition_subscriber_ = participant_->create_subscriber(qos);
  }
  return any_partition_subscriber_;
}

void Participant::stop_callbacks() {
  std::unique_lock lock(gate_->mutex);
  gate_->closed = true;
}

Participant::~Participant() {
  if (participant_ == nullptr) return;
  // Stops every listener before they are freed (members are destroyed after this body).
  participant_->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

Result<fdds::Topic*> Participant::topic_for_type(const std::string& name, const fdds::TypeSupport& type) {
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

fdds::DataWriter* Participant::create_writer(fdds::Topic* topic, QosKind kind, const std::string& partition) {
  fdds::Publisher* pub = publisher_in(partition);
  if (pub == nullptr) return nullptr;
  fdds::DataWriterQos qos;
  {
    std::lock_guard lock(mutex_);
    qos = writer_qos(topic->get_name(), kind, site_notes_);
  }
  auto* w = pub->create_datawriter(topic, qos);
  if (w != nullptr) {
    std::lock_guard lock(mutex_);
    writers_[topic->get_name()].push_back(w);
  }
  return w;
}

fdds::DataReader* Participant::create_reader(fdds::Topic* topic, QosKind kind, int keep_last,
                                             fdds::DataReaderListener* listener, bool any_partition) {
  fdds::DataReaderQos qos;
  {
    std::lock_guard lock(mutex_);
    qos = reader_qos(topic->get_name(), kind, site_notes_);
  }
  if (keep_last > 0 && qos.history().kind == fdds::KEEP_LAST_HISTORY_QOS)
    set_history(qos, fdds::KEEP_LAST_HISTORY_QOS, keep_last);
  fdds::Subscriber* sub = any_partition ? any_partition_subscriber() : subscriber_;
  if (sub == nullptr) return nullptr;
  auto* r = sub->create_datareader(topic, qos, listener);
  if (r != nullptr) {
    std::lock_guard lock(mutex_);
    readers_[topic->get_name()].push_back(r);
  }
  return r;
}

void Participant::remove_reader(fdds::DataReader* reader) {
  if (reader == nullptr) return;  // a planning participant's
  {
    std::lock_guard lock(mutex_);
    for (auto& [name, readers] : readers_) std::erase(readers, reader);
  }
  // Returns once no listener call is running on it, so its listener can be freed after.
  const_cast<fdds::Subscriber*>(reader->get_subscriber())->delete_datareader(reader);
}

void Participant::remove_writer(fdds::DataWriter* writer) {
  {
    std::lock_guard lock(mutex_);
    for (auto& [name, writers] : writers_) std::erase(writers, writer);
  }
  const_cast<fdds::Publisher*>(writer->get_publisher())->delete_datawriter(writer);
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
