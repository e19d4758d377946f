#include "gateways/adapters/diagnostics_gateway.hpp"

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string_view>

#include "can/log_bus.hpp"

#include "dds/topic_names.hpp"
#include "gateways/codecs/nmt_state_msg.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;

namespace {

enum class Replay { none, realtime, fast };

Replay replay_of(const profiles::BusConfig& bus) {
  constexpr std::string_view kLog = "log:";
  if (bus.interface.rfind(kLog, 0) != 0) return Replay::none;
  const auto spec = can::LogBus::parse_spec(std::string_view(bus.interface).substr(kLog.size()));
  return spec && spec->pace == can::LogBus::Pace::fast ? Replay::fast : Replay::realtime;
}

template <std::size_t N>
msg::Histogram to_msg(const Histogram<N>& h) {
  msg::Histogram m;
  m.upper_bounds().assign(h.bounds().begin(), h.bounds().end());
  for (std::size_t i = 0; i < N; ++i) m.cumulative_counts().push_back(h.cumulative(i));
  m.count(h.count());
  m.sum(h.sum());
  return m;
}

std::vector<msg::NamedCount> by_letter(const canopen::NodeStateMachine::Counters& c) {
  std::vector<msg::NamedCount> out;
  for (std::size_t i = 0; i < c.boot_failures_by_letter.size(); ++i) {
    const char letter = static_cast<char>('A' + i);
    const auto count = c.boot_failures_by_letter[i];
    if (count == 0 && canopen::kBootErrorLetters.find(letter) == std::string_view::npos) continue;
    msg::NamedCount n;
    n.name(std::string(1, letter));
    n.count(count);
    out.push_back(std::move(n));
  }
  return out;
}

std::vector<msg::NamedCount> by_class(const canopen::RemoteNode::Stats& s) {
  std::vector<msg::NamedCount> out;
  for (std::size_t i = 0; i < canopen::kEmcyClasses; ++i) {
    msg::NamedCount n;
    n.name(std::string(canopen::to_string(static_cast<canopen::EmcyClass>(i))));
    n.count(s.emergencies_by_class[i]);
    out.push_back(std::move(n));
  }
  return out;
}

}  // namespace

DiagnosticsGateway::DiagnosticsGateway(ddsl::Participant& dds, const std::string& line, std::vector<Bus> buses,
                                       BridgeFields bridge_fields, std::chrono::milliseconds period)
    : dds_(dds),
      line_(line),
      buses_(std::move(buses)),
      bridge_fields_(std::move(bridge_fields)),
      period_(period),
      previous_(buses_.size()),
      bus_snapshots_(buses_.size()),
      node_snapshots_(buses_.size()) {
  auto w = dds.writer<msg::DiagnosticsPubSubType>(ddsl::topic_name(line, ddsl::kBridgeNamespace, "diagnostics"),
                                                  ddsl::QosKind::state);
  if (!w) throw std::runtime_error("diagnostics: " + w.error().message);
  writer_ = *w;
}

DiagnosticsGateway::~DiagnosticsGateway() { stop(); }

void DiagnosticsGateway::start() {
  // A first sample at once, not a period later: clients wait for the bridge's incarnation in it
  // before their first request. The loops have not started, so their state is read here safely.
  for (std::size_t i = 0; i < buses_.size(); ++i) snapshot(i);
  for (std::size_t i = 0; i < buses_.size(); ++i) {
    auto* loop = buses_[i].loop;
    const auto timer = loop->create_timer([this, i] { snapshot(i); });
    loop->arm_timer(timer, period_, period_);
  }
  thread_ = std::thread([this] { publish_loop(); });
}

void DiagnosticsGateway::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void DiagnosticsGateway::snapshot(std::size_t i) {
  const Bus& bus = buses_[i];
  const auto stats = bus.loop->stats();
  const auto now = std::chrono::steady_clock::now();
  auto& prev = previous_[i];
  const double dt = prev.at == std::chrono::steady_clock::time_point{}
                        ? 0.0
                        : std::chrono::duration<double>(now - prev.at).count();
  const std::uint64_t bits = bus.loop->bits_in() + bus.loop->bits_out();

  msg::BusDiagnostics b;
  b.name(bus.config->name);
  b.interface_uri(bus.config->interface);
  // A standby says whether it took the bus over (it masters it) or still stands by.
  b.role(bus.standby == nullptr  ? std::string(profiles::to_string(bus.config->role))
         : bus.standby->active() ? "standby, mastering (took over)"
                                 : "standby");
  b.state(std::string(can::to_string(stats.state)));
  if (bus.standby != nullptr) {
    auto text = bus.standby->describe();
    if (bus.flying != nullptr) text += (text.empty() ? "" : "; ") + ("negotiation: " + bus.flying->describe());
    b.takeover(text);
  }
  b.frames_in(stats.frames_in);
  b.frames_out(stats.frames_out);
  b.error_frames(stats.error_frames);
  b.tx_dropped(stats.tx_dropped);
  b.tx_error_counter(stats.tx_error_counter);
  b.rx_error_counter(stats.rx_error_counter);
  b.bus_offs(stats.bus_offs);
  b.rx_overflows(stats.rx_overflows);
  b.rx_dropped(stats.rx_dropped);
  b.tx_queue_full(stats.tx_queue_full);
  b.reopens(stats.reopens);
  b.record_errors(stats.record_errors);
  const Replay replay = replay_of(*bus.config);
  b.replay(replay != Replay::none);
  if (dt > 0) {
    b.frames_in_per_s(static_cast<double>(stats.frames_in - prev.frames_in) / dt);
    b.frames_out_per_s(static_cast<double>(stats.frames_out - prev.frames_out) / dt);
    b.load_percent(100.0 * static_cast<double>(bits - prev.bits) / dt / static_cast<double>(bus.config->bitrate));
  }
  // A fast replay delivers frames as fast as they are read: a load against wall-clock time would
  // be any number (hundreds of percent), so none is given, from the first snapshot on.
  if (replay == Replay::fast) b.load_percent(-1.0);
  prev = {now, stats.frames_in, stats.frames_out, bits};
  b.handler_failures(bus.loop->handler_failures());
  b.handlers_disabled(bus.loop->handlers_disabled());
  b.frames_unclaimed(bus.loop->frames_unclaimed());
  b.requests_refused(bus.loop->posts_refused());
  b.frames_held(bus.loop->frames_held());
  b.stops_sent_while_held(bus.loop->stops_sent_while_held());
  if (bus.other_master != nullptr) {
    b.other_master_yields(static_cast<std::uint32_t>(bus.other_master->yields()));
    b.other_master_frames(bus.other_master->frames());
    b.yielding_to_other_master(bus.other_master->yielding());
    b.other_master_last(bus.other_master->last());
  }
  if (bus.sync != nullptr) {
    b.sync_period_s(std::chrono::duration<double>(bus.sync->period()).count());
    b.sync_period_deviation_s(to_msg(bus.sync->deviations()));
  }
  if (bus.mandatory != nullptr) {
    b.mandatory_missing(bus.mandatory->missing());
    b.mandatory_state(bus.mandatory->state());
  }

  std::vector<msg::NodeDiagnostics> nodes;
  // Heartbeat times are the frames' own: on a replay, the recording's. Their age is then taken on
  // the recording's clock (from the newest heartbeat of the bus), not against today's date.
  std::int64_t now_ns = ddsl::now_ns();
  if (replay != Replay::none) {
    now_ns = 0;
    for (const auto& d : bus.devices) now_ns = std::max(now_ns, d.node->last_heartbeat_ns());
  }
  for (const auto& d : bus.devices) {
    msg::NodeDiagnostics n;
    n.device(d.config->name);
    n.bus(bus.config->name);
    n.node_id(d.config->node_id);
    n.online(d.node->online());
    n.nmt_state(to_msg(d.node->state()));
    n.boot_state(d.services->boot_state());
    n.node_state(std::string(d.services->node_state()));
    if (bus.mandatory != nullptr) {
      n.mandatory(bus.mandatory->mandatory(d.index));
      n.line_hold(bus.mandatory->hold_of(d.index));
      // The node's hold is the line's, not an operator's: its state and boot state say so.
      if (const auto held = bus.mandatory->held_as(d.index);
          !held.empty() && d.services->state() == canopen::NodeState::stopped_by_operator) {
        n.node_state(std::string(held));
        n.boot_state(n.line_hold());
      }
    }
    // Who holds it and since when, and whether that hold comes from before the bridge restarted
    // (the line's own hold says so in line_hold).
    if (d.hold != nullptr && (bus.mandatory == nullptr || bus.mandatory->held_as(d.index).empty())) {
      if (const auto note = d.hold->note(); !note.empty()) n.boot_state(n.boot_state() + "; " + note);
    }
    n.set_values_at_start(d.node->set_values_at_start());
    const auto& report = d.services->boot_report();
    if (const auto& e = report.error) n.boot_error(to_msg(*e));
    n.last_boot_passed(report.started);
    n.adopted(report.adopted);
    n.product_name(report.identity.device_name);
    const auto& profile = d.config->bridge_profile();
    n.device_type(profile.device);
    n.profile(profile.id + " " + profile.version);
    const auto& errors = d.node->errors();
    n.error_register(errors.error_register());
    n.active_errors(errors.codes());
    n.active_errors_known(errors.known());
    n.active_errors_note(errors.note());
    const auto counters = d.services->boot_counters();
    n.boots(counters.boots);
    n.boot_failures(counters.boot_failures);
    n.state_unknown(counters.state_unknown);
    n.heartbeat_producer_rewrites(counters.heartbeat_producer_rewrites);
    n.resets_spared(counters.resets_spared);
    if (d.services->state()) n.boot_failures_by_letter(by_letter(counters));
    const auto last = d.node->last_heartbeat_ns();
    n.last_heartbeat_age_s(last == 0 ? -1.0 : static_cast<double>(now_ns - last) / 1e9);
    const auto& s = d.node->stats();
    n.boot_ups(s.boot_ups);
    n.pdos_received(s.pdos_received);
    n.pdos_sent(s.pdos_sent);
    n.pdo_length_errors(s.pdo_length_errors);
    n.emergencies(s.emergencies);
    n.range_warnings(s.range_warnings);
    n.malformed_emergencies(s.malformed_emergencies);
    n.malformed_heartbeats(s.malformed_heartbeats);
    n.boot_ups_not_believed(s.boot_ups_not_believed);
    n.states_not_believed(s.states_not_believed);
    n.heartbeats_missing_while_heard(s.heartbeats_missing_while_heard);
    n.heartbeat_judgements_deferred(d.node->heartbeat_judgements_deferred());
    n.emergencies_by_class(by_class(s));
    if (bus.sdo != nullptr) n.sdo_duration_s(to_msg(bus.sdo->durations(d.config->node_id)));
    nodes.push_back(std::move(n));
  }
  std::lock_guard lock(mutex_);
  bus_snapshots_[i] = std::move(b);
  node_snapshots_[i] = std::move(nodes);
}

// The loops take the mutex only to store their snapshots; the DDS write, which may take a while,
// happens after it is released so that no bus loop ever waits for it.
void DiagnosticsGateway::publish_loop() {
  std::unique_lock lock(mutex_);
  do {
    msg::Diagnostics d;
    const auto stamp = ddsl::to_stamp(ddsl::now_ns());
    d.stamp().sec(stamp.sec);
    d.stamp().nanosec(stamp.nanosec);
    d.line(line_);
    d.buses(bus_snapshots_);
    for (const auto& nodes : node_snapshots_) d.nodes().insert(d.nodes().end(), nodes.begin(), nodes.end());
    lock.unlock();
    d.commands_lost(dds_.commands_lost());
    d.bridge_incarnation(dds_.incarnation());  // what clients name in their requests to this run
    if (bridge_fields_) bridge_fields_(d);
    writer_.write(d);
    lock.lock();
  } while (!cv_.wait_for(lock, period_, [this] { return stopping_; }));
}

}  // namespace lb::gateways
