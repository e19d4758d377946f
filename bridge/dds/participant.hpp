#pragma once
// A DDS participant with the project's QoS conventions, and typed writers and readers on it.
// Namespace ddsl, not dds: a global ::dds in Fast DDS headers collides with the obvious alias.

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "base/result.hpp"
#include "dds/cdr.hpp"
#include "dds/channel_identity.hpp"
#include "dds/discovery_gate.hpp"
#include "dds/incarnation.hpp"
#include "dds/lost_samples.hpp"
#include "dds/security_files.hpp"
#include "dds/topic_names.hpp"
#include "dds/writer_partitions.hpp"
#include "link/bus_channel.hpp"

namespace lb::ddsl {

namespace fdds = eprosima::fastdds::dds;

// What a topic carries decides its QoS; writers and readers of a kind always match.
enum class QosKind {
  state,    // reliable, transient-local, keep-last 1: late joiners get the current state
  command,  // reliable, volatile, keep-last 16: set values and requests, never replayed to late joiners
  event,    // reliable, volatile, keep-last 1000: every cut, every emergency (a frozen reader never blocks a writer)
  // reliable, transient-local, keep-last 16: answers (service replies, set-value results). A
  // client's new reader may be matched by the client before the server's writer has matched it;
  // transient-local lets the reader still get the answer written in that gap.
  reply,
};

// A Fast DDS discovery server (fast-discovery-server -i ID -l ADDRESS -p PORT): its ID gives its
// GUID prefix, as ROS_DISCOVERY_SERVER's positions do.
struct DiscoveryServer {
  std::uint8_t id = 0;
  std::string address;  // IPv4
  std::uint16_t port = 11811;
};

// What discovery reports of remote participants and endpoints, for tools that list a line.
struct DiscoveryEvent {
  enum class Kind { participant, writer, reader };
  Kind kind = Kind::participant;
  bool removed = false;
  std::string guid;        // the participant's GUID prefix or the endpoint's GUID
  std::string name;        // the participant's name or the endpoint's topic
  std::string type;        // the endpoint's type name
  std::string qos;         // "reliable, transient-local" ...
  std::string partitions;  // comma-separated
};
using DiscoveryObserver = std::function<void(const DiscoveryEvent&)>;

struct ParticipantOptions {
  std::uint32_t domain = 0;
  bool localhost_only = true;  // UDPv4 on 127.0.0.1 only, initial peer 127.0.0.1
  std::string name = "linebridge";
  // DDS Security (PKI-DH, Access-Permissions, AES-GCM-GMAC), fail-closed: the files are checked
  // first and the participant proves after creation that security is in force, or it is not created.
  std::optional<SecurityFiles> security = std::nullopt;
  // Site DDS configuration (README "Site DDS configuration"): Fast DDS XML profiles, loaded after
  // FASTRTPS_DEFAULT_PROFILES_FILE; a participant profile by name ("" = the file's default one).
  std::string profiles_file = {};
  std::string participant_profile = {};
  // Discovery through these servers (CLIENT) instead of multicast; none: simple discovery.
  std::vector<DiscoveryServer> discovery_servers = {};
  // With discovery servers: learn every endpoint of the domain (SUPER_CLIENT), for tools that
  // list a line's topics; a plain client learns only the endpoints that match its own.
  bool see_all_endpoints = false;
  DiscoveryObserver on_discovery = {};
  // Fast DDS's shared-memory transport besides UDP. Off by default: in Fast DDS 2.9 it silently
  // carries nothing between processes of different users (the service's and an operator's).
  bool shared_memory = false;
  // The discovery gate in front of the transports (discovery_gate.hpp): what remote participants
  // that have not proven themselves (authenticated, on a secured participant) may make this one
  // hold. Simple discovery only: a discovery server's client takes announcements from its servers
  // alone already.
  GateLimits gate = {};
};

// Remote participants as this participant's discovery reported them.
struct RemoteCounts {
  int known = 0;               // announced and not gone (on a secured participant: authenticated or pending)
  std::uint64_t refused = 0;   // failed authentication since start (secured participants)
  std::uint64_t departed = 0;  // removed or dropped (lease expired) since start
};

// A DDS entity the bridge would create, as a planning participant records it (linebridge --check).
struct PlannedEndpoint {
  std::string topic;
  std::string type;
  QosKind kind = QosKind::state;
  bool writer = true;
  std::string partition;  // "*" for a reader of every partition
};
std::string_view to_string(QosKind kind);  // "reliable, transient-local, keep-last 1" ...

// Why a participant was not created. `configuration`: the options are wrong (a security file,
// security not in force), not the machine; executables exit with their configuration-error code.
struct CreateError {
  std::string message;
  bool configuration = false;
};

// The QoS Participant::create gives Fast DDS, site profiles and security properties included,
// without the checks and the proof: for tests that must drive Fast DDS directly (a client that
// bypasses its own checks). Site notes: what a profile set that was not applied, and why.
// With `gate`, every transport but shared memory sits behind it (simple discovery only).
Result<fdds::DomainParticipantQos> participant_qos(const ParticipantOptions& options, std::vector<std::string>* notes,
                                                   const std::shared_ptr<DiscoveryGate>& gate = nullptr);
inline fdds::DomainParticipantQos participant_qos(const ParticipantOptions& options) {
  auto qos = participant_qos(options, nullptr);
  return qos ? *qos : fdds::PARTICIPANT_QOS_DEFAULT;
}

// ROS 2 style service topic names: rq/<path>Request and rr/<path>Reply.
inline std::string request_topic(const std::string& path) { return "rq/" + path + "Request"; }
inline std::string reply_topic(const std::string& path) { return "rr/" + path + "Reply"; }

// Seconds and nanoseconds since the epoch of a CLOCK_REALTIME time in ns.
struct Stamp {
  std::int32_t sec;
  std::uint32_t nanosec;
};
constexpr Stamp to_stamp(std::int64_t ns) {
  return {static_cast<std::int32_t>(ns / 1'000'000'000), static_cast<std::uint32_t>(ns % 1'000'000'000)};
}
std::int64_t now_ns();
// Every sample type of the contract has a `stamp` (builtin_interfaces/Time).
template <class Sample>
void set_stamp(Sample& sample, std::int64_t ns) {
  const auto s = to_stamp(ns);
  sample.stamp().sec(s.sec);
  sample.stamp().nanosec(s.nanosec);
}

template <class PubSubType>
class Writer {
 public:
  using Sample = typename PubSubType::type;
  Writer() = default;
  explicit Writer(fdds::DataWriter* writer) : writer_(writer) {}
  // A writer of the DDS process, reached through the channel (a bus process's participant).
  Writer(link::BusChannel& channel, std::uint32_t id) : channel_(&channel), id_(id) {}

  // Thread-safe (Fast DDS serialises writes). False when the writer refused the sample. Over the
  // channel: true once handed on (the channel counts what it drops).
  bool write(const Sample& sample) const {
    if (channel_ != nullptr) {
      channel_->publish(id_, to_cdr(sample));
      return true;
    }
    return writer_ != nullptr && writer_->write(const_cast<Sample*>(&sample));  // API takes void*
  }
  // With parameters: the related sample identity of a reply in, the written sample's identity out
  // (not over the channel: the DDS process writes it later).
  bool write(const Sample& sample, eprosima::fastrtps::rtps::WriteParams& params) const {
    if (channel_ != nullptr) {
      channel_->publish(id_, to_cdr(sample), to_link(params.related_sample_identity()));
      return true;
    }
    return writer_ != nullptr && writer_->write(const_cast<Sample*>(&sample), params);
  }
  eprosima::fastrtps::rtps::GUID_t guid() const { return writer_->guid(); }
  fdds::DataWriter* entity() const { return writer_; }
  int matched() const {
    if (writer_ == nullptr) return 0;
    fdds::PublicationMatchedStatus status;
    writer_->get_publication_matched_status(status);
    return status.current_count;
  }

 private:
  fdds::DataWriter* writer_ = nullptr;
  link::BusChannel* channel_ = nullptr;
  std::uint32_t id_ = 0;
};

struct RemoteTally;  // what the discovery callbacks counted (participant.cpp)

template <class PubSubType>
using SampleCallback = std::function<void(const typename PubSubType::type&, const fdds::SampleInfo&)>;

class Participant {
  struct Key {};  // only create() can construct a participant, yet make_unique can call it

 public:
  explicit Participant(Key) {}
  static Result<std::unique_ptr<Participant>> create(const ParticipantOptions& options);
  static Result<std::unique_ptr<Participant>, CreateError> create_checked(const ParticipantOptions& options);
  // A participant that creates nothing in DDS and records every topic, writer and reader asked of
  // it (with the QoS the site profiles would give them): what a line will publish, without a
  // network (linebridge --check). Its writers write nothing.
  static Result<std::unique_ptr<Participant>, CreateError> plan(const ParticipantOptions& options);
  const std::vector<PlannedEndpoint>& planned() const { return planned_; }
  // A bus process's participant (docs/bus-isolation.md): no DDS entity at all. Its writers and
  // readers are declared to the DDS process through `channel` (which must outlive it), samples
  // cross it as CDR; the service servers, their ledgers and the run (incarnation: the channel's)
  // stay on this side, so a restarted DDS process changes nothing a client can tell but a pause.
  static std::unique_ptr<Participant> over_channel(const ParticipantOptions& options, link::BusChannel& channel);
  const link::BusChannel* channel() const { return channel_; }
  link::BusChannel* channel() { return channel_; }
  // Over the channel: the lane (link::BusChannel::add_lane) of the readers subscribed from now on,
  // whose callbacks then run on the thread that reads the lane (its bus loop); 0: the channel's
  // own thread. Set while one bus's devices are created (app/line_bridge.cpp).
  void set_reader_lane(std::uint32_t lane) { reader_lane_ = lane; }
  // What the site's profiles set that was not applied (contract QoS, transports over
  // localhost_only, ...), one line each, for the log and --check.
  std::vector<std::string> site_notes() const;
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  template <class PubSubType>
  Result<Writer<PubSubType>> writer(const std::string& topic, QosKind kind) {
    if (planning_) return plan_endpoint<PubSubType, Writer<PubSubType>>(topic, kind, true);
    if (channel_ != nullptr) return channel_writer<PubSubType>(topic, kind, {});
    auto t = topic_for<PubSubType>(topic);
    if (!t) return t.error();
    auto* w = create_writer(*t, kind);
    if (w == nullptr) return make_error("cannot create DDS writer on " + topic);
    return Writer<PubSubType>(w);
  }

  // A writer in one DDS partition (a device's, for line-wide requests in a secured line). Fails
  // when the permissions do not grant publishing on the topic in that partition.
  template <class PubSubType>
  Result<Writer<PubSubType>> writer(const std::string& topic, QosKind kind, const std::string& partition) {
    if (planning_) return plan_endpoint<PubSubType, Writer<PubSubType>>(topic, kind, true, partition);
    if (channel_ != nullptr) return channel_writer<PubSubType>(topic, kind, partition);
    auto t = topic_for<PubSubType>(topic);
    if (!t) return t.error();
    auto* w = create_writer(*t, kind, partition);
    if (w == nullptr) {
      return make_error("cannot create DDS writer on " + topic + " in partition '" + partition + "'" +
                        (secured_ ? " (do this identity's permissions grant it?)" : ""));
    }
    return Writer<PubSubType>(w);
  }

  // The callback runs on a Fast DDS thread, once per valid sample, in arrival order per writer.
  // keep_last > 0 deepens a keep-last reader's history, for a subscriber that must see every
  // sample of a state topic rather than the latest.
  template <class PubSubType>
  Result<void> subscribe(const std::string& topic, QosKind kind, SampleCallback<PubSubType> callback,
                         int keep_last = 0) {
    if (planning_) return plan_endpoint<PubSubType, void>(topic, kind, false);
    if (channel_ != nullptr) return channel_reader<PubSubType>(topic, kind, std::move(callback), keep_last, false);
    auto t = topic_for<PubSubType>(topic);
    if (!t) return t.error();
    auto listener = std::make_unique<TypedListener<PubSubType>>(std::move(callback), gate_, lost_for(kind), topic);
    if (create_reader(*t, kind, keep_last, listener.get()) == nullptr) {
      return make_error("cannot create DDS reader on " + topic);
    }
    std::lock_guard lock(mutex_);
    listeners_.push_back(std::move(listener));
    return {};
  }

  // A subscription that ends with the returned object (the DataReader is deleted, its listener
  // freed after Fast DDS stopped calling it): for short-lived subscribers such as service clients.
  class Subscription {
   public:
    Subscription(Participant& owner, fdds::DataReader* reader, std::unique_ptr<fdds::DataReaderListener> listener)
        : owner_(owner), reader_(reader), listener_(std::move(listener)) {}
    ~Subscription() { owner_.remove_reader(reader_); }
    Subscription(const Subscription&) = delete;
    Subscription& operator=(const Subscription&) = delete;

   private:
    Participant& owner_;
    fdds::DataReader* reader_;
    std::unique_ptr<fdds::DataReaderListener> listener_;
  };

  template <class PubSubType>
  Result<std::unique_ptr<Subscription>> subscribe_scoped(const std::string& topic, QosKind kind,
                                                         SampleCallback<PubSubType> callback) {
    if (planning_) {
      record_plan(PlannedEndpoint{topic, PubSubType().getName(), kind, false, {}});
      return std::make_unique<Subscription>(*this, nullptr, nullptr);
    }
    if (channel_ != nullptr)
      return make_error("a scoped subscription needs a DDS participant, not a channel: " + topic);
    auto t = topic_for<PubSubType>(topic);
    if (!t) return t.error();
    auto listener = std::make_unique<TypedListener<PubSubType>>(std::move(callback), gate_, lost_for(kind), topic);
    auto* reader = create_reader(*t, kind, 0, listener.get());
    if (reader == nullptr) return make_error("cannot create DDS reader on " + topic);
    return std::make_unique<Subscription>(*this, reader, std::move(listener));
  }
  // A reader of writers in any DDS partition ("*"), for the line-wide requests of a secured line;
  // writer_in_partition() tells which partitions a sample's writer was matched with.
  template <class PubSubType>
  Result<void> subscribe_any_partition(const std::string& topic, QosKind kind, SampleCallback<PubSubType> callback) {
    if (planning_) return plan_endpoint<PubSubType, void>(topic, kind, false, "*");
    if (channel_ != nullptr) return channel_reader<PubSubType>(topic, kind, std::move(callback), 0, true);
    auto t = topic_for<PubSubType>(topic);
    if (!t) return t.error();
    auto listener = std::make_unique<TypedListener<PubSubType>>(std::move(callback), gate_, lost_for(kind), topic);
    if (create_reader(*t, kind, 0, listener.get(), true) == nullptr) {
      return make_error("cannot create DDS reader on " + topic + " in every partition");
    }
    std::lock_guard lock(mutex_);
    listeners_.push_back(std::move(listener));
    return {};
  }
  void remove_writer(fdds::DataWriter* writer);

  // The DDS process's endpoints (app/dds_side.hpp): of a type it knows only by name and size, as
  // the bus process declared it, samples as CDR bytes (raw_type.hpp). The callback runs on a Fast
  // DDS thread with the sample's info and, for an any-partition reader, the partitions its writer
  // is trusted in.
  Result<fdds::DataWriter*> raw_writer(const link::Declare& declaration);
  using RawCallback = std::function<void(const std::vector<std::uint8_t>& cdr, const fdds::SampleInfo& info,
                                         std::vector<std::string> partitions)>;
  Result<void> subscribe_raw(const link::Declare& declaration, RawCallback callback);

  // Any thread but a callback's: waits for the sample callbacks running now and lets no other run
  // after it returns (samples are then left unread). For an orderly shutdown: what the callbacks
  // reach (SDO clients, gateways) may be destroyed afterwards while the writers still exist, so
  // answers still pending can go out.
  void stop_callbacks();

  // Set values and requests clients wrote that never reached a callback (dds/lost_samples.hpp).
  std::uint64_t commands_lost() const { return lost_commands_->lost(); }

  // Remote participants now and since start (discovery callbacks): only those the discovery gate
  // let through reach Fast DDS and these counts.
  RemoteCounts remote_counts() const;
  // What the discovery gate did and holds (all zero without a gate: planning, over the channel,
  // with discovery servers), and what is new since the last call, for a rate-limited log.
  GateCounts gate_counts() const { return discovery_gate_ ? discovery_gate_->counts() : GateCounts{}; }
  std::vector<std::string> gate_news() {
    return discovery_gate_ ? discovery_gate_->take_news() : std::vector<std::string>{};
  }
  bool gated() const { return discovery_gate_ != nullptr; }

  // Created with DDS Security (and proven to be in force).
  bool secured() const { return secured_; }
  // This participant's run, drawn when it was created: the service servers on it answer only
  // requests naming it (or none), and a bridge publishes it in its diagnostics (incarnation.hpp).
  Incarnation incarnation() const { return incarnation_; }
  // Secured participants: whether a remote writer was matched in this partition and is still in
  // it (writer_partitions.hpp). Always false on an unsecured participant.
  bool writer_in_partition(const eprosima::fastrtps::rtps::GUID_t& writer, std::string_view partition) const;

  // Number of matched remote readers/writers on a topic: tests and clients wait on it before their
  // first sample, because DDS discovery is asynchronous.
  int matched_readers(const std::string& topic) const;
  int matched_writers(const std::string& topic) const;

 private:
  // Shared by every listener of the participant: callbacks run under its shared lock, and
  // stop_callbacks() takes it exclusively once.
  struct CallbackGate {
    std::shared_mutex mutex;
    bool closed = false;
  };

  template <class PubSubType>
  class TypedListener : public fdds::DataReaderListener {
   public:
    TypedListener(SampleCallback<PubSubType> cb, std::shared_ptr<CallbackGate> gate,
                  std::shared_ptr<LostSamples> lost = nullptr, std::string topic = {})
        : cb_(std::move(cb)), gate_(std::move(gate)), lost_(std::move(lost)), topic_(std::move(topic)) {}
    void on_data_available(fdds::DataReader* reader) override {
      std::shared_lock lock(gate_->mutex);
      if (gate_->closed) return;
      typename PubSubType::type sample;
      fdds::SampleInfo info;
      while (reader->take_next_sample(&sample, &info) == eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
        if (!info.valid_data) continue;
        if (lost_) lost_->seen(info.sample_identity, topic_);
        cb_(sample, info);
      }
    }

   private:
    SampleCallback<PubSubType> cb_;
    std::shared_ptr<CallbackGate> gate_;
    std::shared_ptr<LostSamples> lost_;  // command readers only
    std::string topic_;
  };

  template <class PubSubType, class Made>
  Result<Made> plan_endpoint(const std::string& topic, QosKind kind, bool writer, const std::string& partition = {}) {
    record_plan(PlannedEndpoint{topic, PubSubType().getName(), kind, writer, partition});
    if constexpr (std::is_void_v<Made>) {
      return {};
    } else {
      return Made();
    }
  }
  void record_plan(PlannedEndpoint endpoint);

  template <class PubSubType>
  static link::Declare declaration(const std::string& topic, QosKind kind, bool writer, const std::string& partition,
                                   int keep_last, bool any_partition, std::uint32_t lane = 0) {
    PubSubType type;
    link::Declare d;
    d.writer = writer;
    d.any_partition = any_partition;
    d.qos_kind = static_cast<std::uint8_t>(kind);
    d.keep_last = keep_last;
    d.max_size = type.m_typeSize;
    d.topic = topic;
    d.type = type.getName();
    d.partition = partition;
    d.lane = lane;
    return d;
  }
  template <class PubSubType>
  Result<Writer<PubSubType>> channel_writer(const std::string& topic, QosKind kind, const std::string& partition) {
    const auto id = channel_->declare(declaration<PubSubType>(topic, kind, true, partition, 0, false),
                                      kind == QosKind::state, kind == QosKind::state && is_status_topic(topic));
    return Writer<PubSubType>(*channel_, id);
  }
  // The channel's thread (or the reader's lane's) runs the callback, as a Fast DDS listener thread
  // would, behind the same gate. An any-partition reader stays on the channel's thread whatever the
  // lane: its callback records the writer's partitions under mutex_, a plain mutex a realtime bus
  // loop must not wait on.
  template <class PubSubType>
  Result<void> channel_reader(const std::string& topic, QosKind kind, SampleCallback<PubSubType> callback,
                              int keep_last, bool any_partition) {
    channel_->declare_reader(declaration<PubSubType>(topic, kind, false, any_partition ? "*" : "", keep_last,
                                                     any_partition, any_partition ? 0 : reader_lane_),
                             [this, cb = std::move(callback), gate = gate_, lost = lost_for(kind), topic,
                              any_partition](const link::Sample& s) {
                               std::shared_lock lock(gate->mutex);
                               if (gate->closed) return;
                               typename PubSubType::type sample;
                               if (!from_cdr(s.payload, sample)) return undecodable(topic);
                               fdds::SampleInfo info;
                               info.valid_data = true;
                               info.sample_identity = from_link(s.identity);
                               info.related_sample_identity = from_link(s.related);
                               if (any_partition) heard_partitions(info.sample_identity.writer_guid(), s.partitions);
                               if (lost) lost->seen(info.sample_identity, topic);
                               cb(sample, info);
                             });
    return {};
  }
  void heard_partitions(const eprosima::fastrtps::rtps::GUID_t& writer, const std::vector<std::string>& partitions);
  void undecodable(const std::string& topic);

  template <class PubSubType>
  Result<fdds::Topic*> topic_for(const std::string& name) {
    // TypeSupport takes ownership of a raw pointer by API design.
    return topic_for_type(name, fdds::TypeSupport(std::make_unique<PubSubType>().release()));
  }
  Result<fdds::Topic*> topic_for_type(const std::string& name, const fdds::TypeSupport& type);
  fdds::DataWriter* create_writer(fdds::Topic* topic, QosKind kind, const std::string& partition = {});
  fdds::DataReader* create_reader(fdds::Topic* topic, QosKind kind, int keep_last, fdds::DataReaderListener* listener,
                                  bool any_partition = false);
  void remove_reader(fdds::DataReader* reader);
  fdds::Publisher* publisher_in(const std::string& partition);
  fdds::Subscriber* any_partition_subscriber();

  std::shared_ptr<LostSamples> lost_for(QosKind kind) const {
    return kind == QosKind::command ? lost_commands_ : nullptr;
  }

  std::shared_ptr<CallbackGate> gate_ = std::make_shared<CallbackGate>();
  std::shared_ptr<LostSamples> lost_commands_ = std::make_shared<LostSamples>();
  // Declared before the participant's entities: Fast DDS calls it until the participant is deleted.
  std::unique_ptr<WriterPartitions> writer_partitions_;
  std::unique_ptr<fdds::DomainParticipantListener> listener_;
  std::shared_ptr<RemoteTally> remote_tally_;
  std::shared_ptr<DiscoveryGate> discovery_gate_;  // shared with the transports Fast DDS made (gate_transport.hpp)
  bool secured_ = false;
  bool planning_ = false;
  Incarnation incarnation_ = draw_incarnation();
  link::BusChannel* channel_ = nullptr;
  std::uint32_t reader_lane_ = 0;
  // Over the channel: the partitions the DDS process last said a writer is in (guarded by mutex_).
  std::map<eprosima::fastrtps::rtps::GUID_t, std::vector<std::string>> channel_partitions_;
  std::chrono::steady_clock::time_point last_undecodable_log_{};
  std::vector<PlannedEndpoint> planned_;
  std::vector<std::string> site_notes_;  // guarded by mutex_
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  mutable std::mutex mutex_;
  std::map<std::string, fdds::Publisher*> partition_publishers_;
  fdds::Subscriber* any_partition_subscriber_ = nullptr;
  std::map<std::string, fdds::Topic*> topics_;
  std::map<std::string, std::vector<fdds::DataWriter*>> writers_;
  std::map<std::string, std::vector<fdds::DataReader*>> readers_;
  std::vector<std::unique_ptr<fdds::DataReaderListener>> listeners_;
};

}  // namespace lb::ddsl
