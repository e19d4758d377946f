// bench-ownership-failover: how long a DDS client is without the saw's status when the bridge that
// writes it dies (SIGKILL: a PC losing power) and the line's other bridge takes over, both ways
// issue 42 named (docs/dds-contract.md, "Two bridges for one line"):
//   exclusive  both bridges write; EXCLUSIVE ownership, A strength 10, B strength 5, a liveliness
//              lease (manual by topic, or automatic): a reader with EXCLUSIVE ownership takes B's
//              samples once A's liveliness is lost or A is unmatched. Not the product's QoS: the
//              state kind's, changed here.
//   standby    the product's: B's participant exists, its writer (the state kind, as the bridge
//              makes it) only once B has decided to take over, takeover_after_ms after it saw A's
//              process end (the bus side's decision, simulated by that fixed delay).
// Beside them: what a reader as every client makes it (the state kind: SHARED) takes from exclusive
// writers, what the EXCLUSIVE reader takes from the product's writers, and the traffic on the
// loopback with both bridges writing and with one.
//
// Every participant is a process of its own (this program again: `reader`, `writer`); their events
// reach the conductor over a pipe (failover_events.hpp). Runs only inside
// launch_scripts/netns-run.sh: a private network namespace, so nothing reaches a real network.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "clock.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "failover_events.hpp"
#include "latencies.hpp"
#include "msgs/sawPubSubTypes.h"
#include "names.hpp"
#include "program.hpp"
#include "security_option.hpp"
#include "stop_signals.hpp"

namespace bench = lb::bench;
namespace fdds = eprosima::fastdds::dds;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using ReturnCode = eprosima::fastrtps::types::ReturnCode_t;

namespace {

constexpr const char* kWriterPrefix = "bench-ownership-w";
constexpr auto kSetup = 30s;  // a process's start and discovery on a loaded machine

std::string status_topic() { return lb::ddsl::topic_name(bench::kLine, bench::device_name(0, 0), "status"); }

eprosima::fastrtps::Duration_t duration_ms(int ms) {
  return eprosima::fastrtps::Duration_t(ms / 1000, (ms % 1000) * 1'000'000u);
}

// How a writer's death is noticed: its liveliness lease, and who asserts it. "none": Fast DDS's
// default and the product's (infinite); then only the dead participant's lease (10 s,
// participant.cpp) unmatches its writers.
//   automatic        the participant asserts it (liveliness messages every announcement period)
//   manual-by-topic  every sample asserts its writer's (so does DataWriter::assert_liveliness)
// Fast DDS 2.9 watches a writer's liveliness only for a reader that asks for a finite lease, under
// the reader's kind and lease (StatefulReader::matched_writer_add), so both sides name them; a
// reader's request is met by an offer of the same kind and lease.
struct Liveliness {
  std::string kind = "none";
  int lease_ms = 0;
};

template <class Qos>
void apply(const Liveliness& l, Qos& qos) {
  if (l.kind == "none") return;
  qos.liveliness().kind = l.kind == "automatic" ? fdds::AUTOMATIC_LIVELINESS_QOS : fdds::MANUAL_BY_TOPIC_LIVELINESS_QOS;
  qos.liveliness().lease_duration = duration_ms(l.lease_ms);
}

// The bench's exclusive variant of the state kind: the QoS the layer gave its writer, with
// EXCLUSIVE ownership, a strength and the liveliness of the case.
fdds::DataWriterQos exclusive_writer_qos(fdds::DataWriterQos qos, int strength, const Liveliness& l) {
  qos.ownership().kind = fdds::EXCLUSIVE_OWNERSHIP_QOS;
  qos.ownership_strength().value = static_cast<std::uint32_t>(strength);
  apply(l, qos);
  // Fast DDS refuses an announcement period that is not below the lease. Half of it: a dead
  // writer's last announcement is then between half a lease and a lease old when its lease ends.
  if (l.kind == "automatic") qos.liveliness().announcement_period = duration_ms(l.lease_ms / 2);
  return qos;
}

// The state kind's reader QoS (participant.cpp: reliable, transient-local, keep-last 1, one
// instance, no data sharing) with EXCLUSIVE ownership and the liveliness of the case. The layer
// makes no such reader and does not hand out its QoS, so it is written out here.
fdds::DataReaderQos exclusive_reader_qos(const Liveliness& l) {
  fdds::DataReaderQos qos = fdds::DATAREADER_QOS_DEFAULT;
  qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = fdds::TRANSIENT_LOCAL_DURABILITY_QOS;
  qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = 1;
  qos.resource_limits().max_instances = 1;
  qos.resource_limits().max_samples = 1;
  qos.resource_limits().max_samples_per_instance = 1;
  qos.resource_limits().allocated_samples = 1;
  qos.data_sharing().off();
  qos.endpoint().history_memory_policy = eprosima::fastrtps::rtps::DYNAMIC_REUSABLE_MEMORY_MODE;
  qos.ownership().kind = fdds::EXCLUSIVE_OWNERSHIP_QOS;
  apply(l, qos);
  return qos;
}

void add_liveliness_options(CLI::App& cmd, Liveliness& l) {
  cmd.add_option("--liveliness", l.kind)->check(CLI::IsMember({"none", "automatic", "manual-by-topic"}));
  cmd.add_option("--lease-ms", l.lease_ms)->check(CLI::Range(2, 60'000));
}

// A sample carries its writer's tag in the status word and its number in the counter: the bench's
// own marks, so the reader can tell A's samples from B's.
void report_sample(char kind, const msg::SawStatus& s) { bench::emit(kind, s.status_word().raw(), s.counter_value()); }

// ---- the writer: one bridge's status writer ----

struct WriterArgs {
  std::uint32_t tag = 1;
  std::string mode = "shared";  // exclusive | shared (the state kind) | standby (shared, once A is gone)
  int strength = 0;
  Liveliness liveliness;
  int period_ms = 20;
  int standby_of = 0;  // the pid whose end the standby waits for
  int takeover_after_ms = 2500;
};

int run_writer(const bench::Program& program, const WriterArgs& a) {
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // never outlives the conductor
  bench::StopSignals stop;
  auto dds = lb::ddsl::Participant::create(
      bench::participant_options(program.domain, kWriterPrefix + std::to_string(a.tag), "", ""));
  if (!dds) return program.fail(dds.error().message);
  auto state_writer = [&dds]() -> lb::Result<fdds::DataWriter*> {
    auto w = (*dds)->writer<msg::SawStatusPubSubType>(status_topic(), lb::ddsl::QosKind::state);
    if (!w) return w.error();
    return w->entity();
  };

  fdds::DataWriter* writer = nullptr;
  if (a.mode == "standby") {
    // The participant is announced; no topic, no writer yet (docs/dds-contract.md).
    const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, a.standby_of, 0));
    if (pidfd < 0) return program.fail(fmt::format("pidfd_open({}) failed", a.standby_of));
    bench::emit('r', a.tag, 0);
    pollfd p{pidfd, POLLIN, 0};
    while (::poll(&p, 1, 100) <= 0) {
      if (stop.requested()) return 0;
    }
    ::close(pidfd);
    bench::emit('d', a.tag, 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(a.takeover_after_ms));
    auto w = state_writer();
    if (!w) return program.fail(w.error().message);
    writer = *w;
    bench::emit('c', a.tag, 0);
  } else if (a.mode == "exclusive") {
    // The layer's state writer gives the QoS; the exclusive writer replaces it at once (it wrote nothing).
    auto base = state_writer();
    if (!base) return program.fail(base.error().message);
    const auto qos = exclusive_writer_qos((*base)->get_qos(), a.strength, a.liveliness);
    fdds::Topic* topic = (*base)->get_topic();
    auto* publisher = const_cast<fdds::Publisher*>((*base)->get_publisher());  // the API hands out const only
    (*dds)->remove_writer(*base);
    writer = publisher->create_datawriter(topic, qos);
    if (writer == nullptr) return program.fail("Fast DDS refused the exclusive writer's QoS");
    bench::emit('r', a.tag, 0);
  } else {
    auto w = state_writer();
    if (!w) return program.fail(w.error().message);
    writer = *w;
    bench::emit('r', a.tag, 0);
  }

  // The status of a saw at the bridge's rate (one per SYNC), the first at once.
  const lb::ddsl::Writer<msg::SawStatusPubSubType> out(writer);
  msg::SawStatus sample;
  sample.status_word().raw(static_cast<std::uint16_t>(a.tag));
  auto due = std::chrono::steady_clock::now();
  for (std::uint32_t seq = 1; !stop.requested(); ++seq) {
    sample.counter_value(seq);
    lb::ddsl::set_stamp(sample, bench::realtime_ns());
    out.write(sample);
    due += std::chrono::milliseconds(a.period_ms);
    std::this_thread::sleep_until(due);
  }
  return 0;
}

// ---- the reader: one client with both readers ----

// Reports the samples it takes, and when a writer's liveliness was lost or it was unmatched, under
// that writer's tag (learnt from its samples).
class ExclusiveListener : public fdds::DataReaderListener {
 public:
  void on_liveliness_changed(fdds::DataReader*, const fdds::LivelinessChangedStatus& status) override {
    if (status.not_alive_count_change > 0) report('l', status.last_publication_handle);
  }
  void on_subscription_matched(fdds::DataReader*, const fdds::SubscriptionMatchedStatus& status) override {
    if (status.current_count_change < 0) report('u', status.last_publication_handle);
  }
  void on_data_available(fdds::DataReader* reader) override {
    msg::SawStatus s;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&s, &info) == ReturnCode::RETCODE_OK) {
      if (!info.valid_data) continue;
      report_sample('x', s);
      std::lock_guard lock(mutex_);
      tags_[info.publication_handle] = s.status_word().raw();
    }
  }

 private:
  void report(char kind, const fdds::InstanceHandle_t& writer) {
    std::lock_guard lock(mutex_);
    if (const auto it = tags_.find(writer); it != tags_.end()) bench::emit(kind, it->second, 0);
  }
  std::mutex mutex_;  // Fast DDS calls from more than one thread
  std::map<fdds::InstanceHandle_t, std::uint32_t> tags_;
};

struct ReaderArgs {
  std::uint32_t tag = 0;
  Liveliness liveliness;  // the EXCLUSIVE reader's
};

int run_reader(const bench::Program& program, const ReaderArgs& a) {
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  bench::StopSignals stop;
  // The client as every client and the CLI make it: the layer's state reader (SHARED).
  auto options = bench::participant_options(program.domain, "bench-ownership-reader", "", "");
  options.on_discovery = [](const lb::ddsl::DiscoveryEvent& e) {
    const std::string prefix = kWriterPrefix;
    if (e.kind != lb::ddsl::DiscoveryEvent::Kind::participant || e.removed || e.name.rfind(prefix, 0) != 0) return;
    bench::emit('p', static_cast<std::uint32_t>(std::stoul(e.name.substr(prefix.size()))), 0);
  };
  auto dds = lb::ddsl::Participant::create(options);
  if (!dds) return program.fail(dds.error().message);
  if (auto r = (*dds)->subscribe<msg::SawStatusPubSubType>(status_topic(), lb::ddsl::QosKind::state,
                                                           [](const msg::SawStatus& s, const fdds::SampleInfo&) {
                                                             report_sample('s', s);
                                                           });
      !r) {
    return program.fail(r.error().message);
  }

  // The EXCLUSIVE reader, on a participant of its own with the layer's participant QoS.
  ExclusiveListener listener;  // outlives the participant below, which calls it
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  auto remove = [factory](fdds::DomainParticipant* p) {
    p->delete_contained_entities();
    factory->delete_participant(p);
  };
  std::unique_ptr<fdds::DomainParticipant, decltype(remove)> participant(
      factory->create_participant(static_cast<fdds::DomainId_t>(program.domain),
                                  lb::ddsl::participant_qos(bench::participant_options(
                                      program.domain, "bench-ownership-exclusive-reader", "", ""))),
      remove);
  if (!participant) return program.fail("cannot create the exclusive reader's participant");
  fdds::TypeSupport type(std::make_unique<msg::SawStatusPubSubType>().release());  // takes the raw pointer
  type.register_type(participant.get());
  auto* topic = participant->create_topic(status_topic(), type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  auto* subscriber = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (topic == nullptr || subscriber == nullptr ||
      subscriber->create_datareader(topic, exclusive_reader_qos(a.liveliness), &listener) == nullptr) {
    return program.fail("cannot create the exclusive reader");
  }
  bench::emit('r', a.tag, 0);
  stop.wait();
  return 0;
}

// ---- the conductor ----

// A process of this program, its events on fd 3.
class Child {
 public:
  Child(const std::string& exe, std::vector<std::string> args, int events_fd) {
    args.insert(args.begin(), exe);
    std::vector<char*> argv;
    for (auto& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, events_fd, bench::kEventsFd);
    if (posix_spawn(&pid_, exe.c_str(), &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  Child(Child&& other) noexcept : pid_(std::exchange(other.pid_, -1)) {}
  Child& operator=(Child&& other) noexcept {
    if (this != &other) {
      kill_now();
      pid_ = std::exchange(other.pid_, -1);
    }
    return *this;
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child() { kill_now(); }

  pid_t pid() const { return pid_; }
  bool started() const { return pid_ > 0; }
  // Power lost: no goodbye on the wire.
  void kill_now() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    for (int i = 0; i < 100; ++i) {
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        return;
      }
      std::this_thread::sleep_for(20ms);
    }
    kill_now();
  }

 private:
  pid_t pid_ = -1;
};

// What the loopback carried (this namespace's only interface: every DDS packet of the run).
struct Wire {
  std::uint64_t packets = 0, bytes = 0;
};
Wire loopback() {
  std::ifstream in("/proc/self/net/dev");
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::istringstream fields(line.substr(0, colon) + " " + line.substr(colon + 1));
    std::string name;
    Wire w;
    if (!(fields >> name) || name != "lo") continue;
    fields >> w.bytes >> w.packets;
    return w;
  }
  return {};
}

std::size_t samples_taken(const std::map<std::uint32_t, bench::Heard>& heard) {
  std::size_t n = 0;
  for (const auto& [tag, h] : heard) n += h.exclusive.size() + h.shared.size();
  return n;
}

// The wire and the reader over a window: packets/s, bytes/s, samples the reader took per second.
struct Traffic {
  double packets_per_s = 0, bytes_per_s = 0, taken_per_s = 0;
};
Traffic measure_traffic(bench::EventLog& log, std::chrono::milliseconds window) {
  const auto taken0 = log.read(samples_taken);
  const auto w0 = loopback();
  const auto t0 = bench::monotonic_ns();
  std::this_thread::sleep_for(window);
  const auto w1 = loopback();
  const auto t1 = bench::monotonic_ns();
  const auto taken1 = log.read(samples_taken);
  const double s = static_cast<double>(t1 - t0) / 1e9;
  return {static_cast<double>(w1.packets - w0.packets) / s, static_cast<double>(w1.bytes - w0.bytes) / s,
          static_cast<double>(taken1 - taken0) / s};
}

struct Gaps {
  std::vector<std::int64_t> gap_ns;      // the reader's last sample from the dead writer to its first from the other
  std::vector<std::int64_t> kill_ns;     // SIGKILL to that first sample
  std::vector<std::int64_t> created_ns;  // standby: its writer created to that first sample
  int missed = 0;                        // no sample from the other writer within the deadline
};

std::string ms(std::int64_t ns) { return fmt::format("{:.1f}", static_cast<double>(ns) / 1e6); }
std::string p50_max(std::vector<std::int64_t> ns) {
  if (ns.empty()) return "none";
  std::sort(ns.begin(), ns.end());
  return fmt::format("p50 {} / max {} (min {}) ms", ms(bench::percentile(ns, 0.5)), ms(ns.back()), ms(ns.front()));
}

struct ConductorArgs {
  int reps = 20;
  std::vector<int> manual_leases_ms{100, 250, 500, 1000};
  std::vector<int> automatic_leases_ms{250};
  int automatic_reps = 3;  // each waits for a dead participant's lease: 10 s
  int period_ms = 20;
  int takeover_after_ms = 2500;
  int traffic_ms = 2000;
  unsigned seed = 1;
};

class Conductor {
 public:
  Conductor(const bench::Program& program, const ConductorArgs& args, std::string exe, int events_fd,
            bench::EventLog& log)
      : program_(program), args_(args), exe_(std::move(exe)), events_fd_(events_fd), log_(log), rng_(args.seed) {}

  Child writer(std::uint32_t tag, const std::string& mode, std::vector<std::string> more = {}) {
    std::vector<std::string> a{"writer", "--domain",          std::to_string(program_.domain),
                               "--tag",  std::to_string(tag), "--mode",
                               mode,     "--period-ms",       std::to_string(args_.period_ms)};
    a.insert(a.end(), more.begin(), more.end());
    return Child(exe_, std::move(a), events_fd_);
  }
  // A client; its EXCLUSIVE reader asks for this liveliness. Waits until it is ready.
  Child reader(const Liveliness& l) {
    const auto tag = next_tag();
    std::vector<std::string> a{"reader", "--domain",          std::to_string(program_.domain),
                               "--tag",  std::to_string(tag), "--liveliness",
                               l.kind};
    if (l.kind != "none") a.insert(a.end(), {"--lease-ms", std::to_string(l.lease_ms)});
    Child child(exe_, std::move(a), events_fd_);
    const bool ready = child.started() && log_.wait(kSetup, [tag](const auto& heard) {
      const auto it = heard.find(tag);
      return it != heard.end() && it->second.ready >= 0;
    });
    if (!ready) child.kill_now();
    return child;
  }
  // The first liveliness loss ('l') or unmatch ('u') the EXCLUSIVE reader reported of the writer
  // tagged `writer` after `after`, if any yet.
  std::int64_t reported_after(std::uint32_t writer, bool unmatched, std::int64_t after) {
    return log_.read([&](const auto& heard) -> std::int64_t {
      const auto it = heard.find(writer);
      if (it == heard.end()) return -1;
      const auto& v = unmatched ? it->second.unmatched : it->second.lost;
      const auto at = std::upper_bound(v.begin(), v.end(), after);
      return at == v.end() ? -1 : *at;
    });
  }

  // Until the reader took `count` samples of the writer tagged `tag` (exclusive or shared reader).
  bool taken(std::uint32_t tag, bool exclusive, std::size_t count, std::chrono::milliseconds timeout) {
    return log_.wait(timeout, [&](const auto& heard) {
      const auto it = heard.find(tag);
      return it != heard.end() && (exclusive ? it->second.exclusive : it->second.shared).size() >= count;
    });
  }
  // After a writer died: its last sample at the reader and the other writer's first after it, once
  // there is one (judged anew on every event: a sample of the dead one still in flight counts).
  // {-1, -1} if none came within timeout.
  std::pair<std::int64_t, std::int64_t> switch_over(std::uint32_t dead, std::uint32_t next, bool exclusive,
                                                    std::chrono::milliseconds timeout) {
    std::pair<std::int64_t, std::int64_t> found{-1, -1};
    log_.wait(timeout, [&](const auto& heard) {
      const auto d = heard.find(dead);
      const auto n = heard.find(next);
      if (d == heard.end() || n == heard.end()) return false;
      const auto& dv = exclusive ? d->second.exclusive : d->second.shared;
      const auto& nv = exclusive ? n->second.exclusive : n->second.shared;
      if (dv.empty()) return false;
      const auto at = std::upper_bound(nv.begin(), nv.end(), dv.back());
      if (at == nv.end()) return false;
      found = {dv.back(), *at};
      return true;
    });
    return found;
  }
  void pause_up_to(int ms) {
    if (ms <= 0) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(std::uniform_int_distribution<int>(0, ms - 1)(rng_)));
  }
  Traffic traffic() { return measure_traffic(log_, std::chrono::milliseconds(args_.traffic_ms)); }
  std::uint32_t next_tag() { return ++tag_; }
  const ConductorArgs& args() const { return args_; }
  bench::EventLog& log() { return log_; }

 private:
  const bench::Program& program_;
  const ConductorArgs& args_;
  std::string exe_;
  int events_fd_;
  bench::EventLog& log_;
  std::mt19937 rng_;
  std::uint32_t tag_ = 0;
};

std::string traffic_text(const Traffic& t) {
  return fmt::format("{:.0f} packets/s, {:.0f} bytes/s on the wire; reader took {:.1f} samples/s", t.packets_per_s,
                     t.bytes_per_s, t.taken_per_s);
}

// What the wire carries with one bridge writing the status and with two, before any process was
// killed (a killed participant is still announced to, and its readers sent to, until its lease
// ends): every process is stopped in order, so none lingers into the next figure.
bool traffic_phase(Conductor& c) {
  auto figure = [&c](const char* what) {
    // Past the last start's burst: its initial announcements (5 at 50 ms) and endpoint discovery.
    std::this_thread::sleep_for(1s);
    std::fputs(fmt::format("traffic, {}: {}\n", what, traffic_text(c.traffic())).c_str(), stdout);
  };
  Child reader = c.reader(Liveliness{"manual-by-topic", 250});
  if (!reader.started()) return false;
  figure("the reader alone (its two participants)");
  {
    const auto m = c.next_tag();
    Child master = c.writer(m, "shared");
    if (!master.started() || !c.taken(m, false, 3, kSetup)) return false;
    figure("the product's writer alone");
    const auto s = c.next_tag();
    Child standby = c.writer(s, "standby", {"--standby-of", std::to_string(master.pid())});
    if (!standby.started() || !c.log().wait(kSetup, [s](const auto& heard) {
          return heard.count(s) != 0 && heard.at(s).ready >= 0 && heard.at(s).discovered >= 0;
        }))
      return false;
    figure("the product's writer and a silent standby");
    standby.stop();
    master.stop();
  }
  const std::vector<std::string> live{"--liveliness", "manual-by-topic", "--lease-ms", "250"};
  auto with = [&live](std::vector<std::string> a) {
    a.insert(a.end(), live.begin(), live.end());
    return a;
  };
  const auto b = c.next_tag();
  Child writer_b = c.writer(b, "exclusive", with({"--strength", "5"}));
  if (!writer_b.started() || !c.taken(b, true, 3, kSetup)) return false;
  figure("exclusive B alone (manual-by-topic, lease 250 ms)");
  const auto a = c.next_tag();
  Child writer_a = c.writer(a, "exclusive", with({"--strength", "10"}));
  if (!writer_a.started() || !c.taken(a, true, 3, kSetup)) return false;
  figure("exclusive A and B writing");
  writer_a.stop();
  writer_b.stop();
  reader.stop();
  return true;
}

// Exclusive ownership with one liveliness: a client whose EXCLUSIVE reader asks for it; B
// (strength 5) writes throughout; A (strength 10) is started, takes over, and is killed, reps times.
struct ExclusiveCase {
  Gaps gaps;
  std::vector<std::int64_t> lost_ns;       // SIGKILL to the reader's "liveliness lost"
  std::vector<std::int64_t> unmatched_ns;  // SIGKILL to the reader's "writer unmatched"
};
ExclusiveCase exclusive_case(Conductor& c, const Liveliness& l, int reps, std::vector<std::uint32_t>& tags) {
  ExclusiveCase out;
  auto& g = out.gaps;
  Child reader = c.reader(l);
  auto writer = [&](std::uint32_t tag, int strength) {
    std::vector<std::string> a{"--strength", std::to_string(strength), "--liveliness", l.kind};
    if (l.kind != "none") a.insert(a.end(), {"--lease-ms", std::to_string(l.lease_ms)});
    return c.writer(tag, "exclusive", std::move(a));
  };
  const auto b_tag = c.next_tag();
  tags.push_back(b_tag);
  Child b = writer(b_tag, 5);
  if (!reader.started() || !b.started() || !c.taken(b_tag, true, 3, kSetup)) {
    std::fprintf(stderr, "bench-ownership-failover: writer B never reached the exclusive reader\n");
    g.missed = reps;
    return out;
  }
  // Manual by topic: A's lease runs from its last sample. Otherwise the switch may wait for the
  // dead participant's lease (10 s, participant.cpp).
  const auto deadline = l.kind == "manual-by-topic" ? std::chrono::milliseconds(3 * l.lease_ms) + 5s
                                                    : std::chrono::milliseconds(60s);
  for (int rep = 0; rep < reps; ++rep) {
    const auto a_tag = c.next_tag();
    tags.push_back(a_tag);
    Child a = writer(a_tag, 10);
    if (!a.started() || !c.taken(a_tag, true, 3, kSetup)) {
      ++g.missed;
      continue;
    }
    // Any moment of what asserts A's liveliness: its announcement period, or its write period.
    c.pause_up_to(l.kind == "automatic" ? l.lease_ms / 2 : c.args().period_ms);
    const auto killed = bench::monotonic_ns();
    a.kill_now();
    const auto [last_a, first_b] = c.switch_over(a_tag, b_tag, true, deadline);
    if (first_b < 0) {
      ++g.missed;
      continue;
    }
    g.gap_ns.push_back(first_b - last_a);
    g.kill_ns.push_back(first_b - killed);
    if (const auto t = c.reported_after(a_tag, false, killed); t >= 0) out.lost_ns.push_back(t - killed);
    if (const auto t = c.reported_after(a_tag, true, killed); t >= 0) out.unmatched_ns.push_back(t - killed);
  }
  return out;
}

// The product's scheme: the master writes; the standby's participant waits, and creates its writer
// takeover_after_ms after it saw the master's process end. It then is the master, and a new standby
// starts beside it (as in the takeover test, the roles alternate). The client: the same process,
// its default reader.
Gaps standby_silent(Conductor& c, std::vector<std::uint32_t>& tags) {
  Gaps g;
  Child reader = c.reader(Liveliness{});
  auto master_tag = c.next_tag();
  tags.push_back(master_tag);
  Child master = c.writer(master_tag, "shared");
  if (!reader.started() || !master.started() || !c.taken(master_tag, false, 3, kSetup)) {
    std::fprintf(stderr, "bench-ownership-failover: the first master never reached the reader\n");
    g.missed = c.args().reps;
    return g;
  }
  for (int rep = 0; rep < c.args().reps; ++rep) {
    const auto standby_tag = c.next_tag();
    tags.push_back(standby_tag);
    Child standby = c.writer(standby_tag, "standby",
                             {"--standby-of", std::to_string(master.pid()), "--takeover-after-ms",
                              std::to_string(c.args().takeover_after_ms)});
    // Ready, and its participant known to the client, as a standby's long is.
    const bool known = standby.started() && c.log().wait(kSetup, [&](const auto& heard) {
      const auto it = heard.find(standby_tag);
      return it != heard.end() && it->second.ready >= 0 && it->second.discovered >= 0;
    });
    if (!known) {
      ++g.missed;
      continue;
    }
    c.pause_up_to(c.args().period_ms);  // any moment of the master's write period
    const auto killed = bench::monotonic_ns();
    master.kill_now();
    const auto [last_master, first] = c.switch_over(master_tag, standby_tag, false,
                                                    std::chrono::milliseconds(c.args().takeover_after_ms) + kSetup);
    if (first < 0) {
      ++g.missed;
      continue;
    }
    g.gap_ns.push_back(first - last_master);
    g.kill_ns.push_back(first - killed);
    const auto created = c.log().read([&](const auto& heard) { return heard.at(standby_tag).created; });
    g.created_ns.push_back(first - created);
    master = std::move(standby);
    master_tag = standby_tag;
  }
  return g;
}

std::size_t sum_over(bench::EventLog& log, const std::vector<std::uint32_t>& tags, bool exclusive) {
  return log.read([&](const auto& heard) {
    std::size_t n = 0;
    for (auto tag : tags) {
      if (auto it = heard.find(tag); it != heard.end())
        n += (exclusive ? it->second.exclusive : it->second.shared).size();
    }
    return n;
  });
}

std::string self_exe() {
  std::string path(4096, '\0');
  const auto n = ::readlink("/proc/self/exe", path.data(), path.size() - 1);
  path.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
  return path;
}

// Every figure, printed as it is measured; how many SIGKILLs found no switch (-1: a process did
// not start).
int measure(Conductor& c, bench::EventLog& log, const ConductorArgs& args) {
  int failures = 0;
  std::fputs(fmt::format("# bench-ownership-failover: the saw's status (SawStatus, {}) every {} ms; {} SIGKILLs of "
                         "the writing process per case; seed {}\n",
                         status_topic(), args.period_ms, args.reps, args.seed)
                 .c_str(),
             stdout);
  if (!traffic_phase(c)) {
    std::fputs("bench-ownership-failover: a process of the traffic figures did not start\n", stderr);
    return -1;
  }
  std::fflush(stdout);

  std::vector<std::uint32_t> exclusive_tags;
  auto exclusive = [&](const Liveliness& l, int reps) {
    if (reps == 0) return;
    const auto e = exclusive_case(c, l, reps, exclusive_tags);
    failures += e.gaps.missed;
    std::fputs(fmt::format("exclusive, liveliness {} lease {} ms: gap (A's last sample to B's first at the "
                           "EXCLUSIVE reader) {}; SIGKILL to B's first {}; SIGKILL to liveliness lost {}; SIGKILL "
                           "to A unmatched {}; missed {} of {}\n",
                           l.kind, l.lease_ms, p50_max(e.gaps.gap_ns), p50_max(e.gaps.kill_ns), p50_max(e.lost_ns),
                           p50_max(e.unmatched_ns), e.gaps.missed, reps)
                   .c_str(),
               stdout);
    std::fflush(stdout);
  };
  for (const int lease : args.manual_leases_ms) exclusive({"manual-by-topic", lease}, args.reps);
  for (const int lease : args.automatic_leases_ms) exclusive({"automatic", lease}, args.automatic_reps);
  const auto shared_from_exclusive = sum_over(log, exclusive_tags, false);
  const auto exclusive_taken = sum_over(log, exclusive_tags, true);
  std::fputs(fmt::format("default (SHARED) reader, samples from the exclusive writers: {} (the EXCLUSIVE reader "
                         "took {})\n",
                         shared_from_exclusive, exclusive_taken)
                 .c_str(),
             stdout);
  std::fflush(stdout);

  std::vector<std::uint32_t> standby_tags;
  const auto g = standby_silent(c, standby_tags);
  failures += g.missed;
  std::fputs(fmt::format("standby silent, takeover decision {} ms after the master's process ended: gap (master's "
                         "last sample to the new master's first at the default reader) {}; SIGKILL to first {}; "
                         "writer created to first {}; missed {}\n",
                         args.takeover_after_ms, p50_max(g.gap_ns), p50_max(g.kill_ns), p50_max(g.created_ns), g.missed)
                 .c_str(),
             stdout);
  std::fputs(fmt::format("EXCLUSIVE reader, samples from the standby scheme's (SHARED) writers: {} (the default "
                         "reader took {})\n",
                         sum_over(log, standby_tags, true), sum_over(log, standby_tags, false))
                 .c_str(),
             stdout);
  return failures;
}

int run_conductor(const bench::Program& program, const ConductorArgs& args, const std::string& command) {
  const auto started = std::chrono::steady_clock::now();
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return program.fail("pipe2 failed");
  // Above fd 3, which each child gets it as (a dup2 onto itself would keep close-on-exec).
  const int write_end = ::fcntl(fds[1], F_DUPFD_CLOEXEC, 10);
  ::close(fds[1]);
  if (write_end < 0) return program.fail("fcntl failed");
  int failures = 0;
  {
    bench::EventLog log(fds[0]);
    Conductor c(program, args, self_exe(), write_end, log);
    failures = measure(c, log, args);  // every child it started has ended
    ::close(write_end);                // the log's thread ends once every write end is closed
  }
  ::close(fds[0]);
  const auto took = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  std::fputs(fmt::format("run time {:.0f} s\nreproduce: launch_scripts/netns-run.sh {}\n", took, command).c_str(),
             stdout);
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  bench::Program program{"bench-ownership-failover",
                         "a client's status gap when the writing bridge dies: exclusive ownership vs a silent standby"};
  auto& cli = program.cli;
  program.add_domain();
  ConductorArgs run;
  cli.add_option("--reps", run.reps, "SIGKILLs per case")->check(CLI::Range(1, 1000))->capture_default_str();
  cli.add_option("--manual-leases", run.manual_leases_ms,
                 "exclusive: manual-by-topic liveliness leases (the writers' and the reader's), ms")
      ->delimiter(',')
      ->check(CLI::Range(2, 60'000))
      ->capture_default_str();
  cli.add_option("--automatic-leases", run.automatic_leases_ms,
                 "exclusive: automatic liveliness leases (the writers' and the reader's), ms")
      ->delimiter(',')
      ->check(CLI::Range(2, 60'000))
      ->capture_default_str();
  cli.add_option("--automatic-reps", run.automatic_reps, "SIGKILLs per automatic lease")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cli.add_option("--period-ms", run.period_ms, "status period: one sample per SYNC (sync_period_ms default 20)")
      ->check(CLI::Range(1, 10'000))
      ->capture_default_str();
  cli.add_option("--takeover-after-ms", run.takeover_after_ms,
                 "standby: its decision this long after the master's process ended (the bus key's default: 2.5 "
                 "master heartbeat periods of 1000 ms)")
      ->check(CLI::Range(0, 60'000))
      ->capture_default_str();
  cli.add_option("--traffic-ms", run.traffic_ms, "window of each traffic figure")->capture_default_str();
  cli.add_option("--seed", run.seed, "the random kill moments")->capture_default_str();

  auto* reader_cmd = cli.add_subcommand("reader", "(internal) the client: a default and an EXCLUSIVE reader");
  auto* writer_cmd = cli.add_subcommand("writer", "(internal) one bridge's status writer");
  WriterArgs w;
  ReaderArgs r;
  for (auto* sub : {reader_cmd, writer_cmd}) sub->add_option("--domain", program.domain);
  reader_cmd->add_option("--tag", r.tag)->required();
  add_liveliness_options(*reader_cmd, r.liveliness);
  writer_cmd->add_option("--tag", w.tag)->required();
  writer_cmd->add_option("--mode", w.mode)->check(CLI::IsMember({"exclusive", "shared", "standby"}));
  writer_cmd->add_option("--strength", w.strength);
  add_liveliness_options(*writer_cmd, w.liveliness);
  writer_cmd->add_option("--period-ms", w.period_ms)->check(CLI::Range(1, 10'000));
  writer_cmd->add_option("--standby-of", w.standby_of);
  writer_cmd->add_option("--takeover-after-ms", w.takeover_after_ms);
  cli.require_subcommand(0, 1);
  if (auto rc = program.parse(argc, argv)) return *rc;

  if (const char* ns = std::getenv("LINEBRIDGE_NETNS"); ns == nullptr || std::string(ns) != "1")
    return program.fail("runs DDS participants: start it through launch_scripts/netns-run.sh");
  if (reader_cmd->parsed()) return run_reader(program, r);
  if (writer_cmd->parsed()) return run_writer(program, w);
  std::string command;
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);
  return run_conductor(program, run, command);
}
