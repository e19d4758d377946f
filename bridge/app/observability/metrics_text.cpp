#include "app/observability/metrics_text.hpp"

#include <prometheus/client_metric.h>
#include <prometheus/metric_family.h>
#include <prometheus/metric_type.h>
#include <prometheus/text_serializer.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "app/version.hpp"

namespace lb::app::obs {
namespace {

namespace msg = linebridge_msgs::msg;
using Labels = std::vector<prometheus::ClientMetric::Label>;
using prometheus::MetricType;

// The families of one exposition, each once, in the order they were first named: a family's
// samples must stand together, and a line's devices are visited one after another.
class Exposition {
 public:
  void gauge(std::string_view name, std::string_view help, Labels labels, double value) {
    auto& m = sample(name, help, MetricType::Gauge, std::move(labels));
    m.gauge.value = value;
  }
  void counter(std::string_view name, std::string_view help, Labels labels, double value) {
    auto& m = sample(name, help, MetricType::Counter, std::move(labels));
    m.counter.value = value;
  }
  // An enum as Prometheus' convention has it: one series per possible value, 1 for the current
  // one and 0 for the others, so that a state's series exists before the state is first taken
  // (alerts and rate() see it change, not appear). A current value outside `known` gets its own.
  void state_set(std::string_view name, std::string_view help, const Labels& labels, std::string_view label,
                 std::span<const std::string_view> known, const std::string& current) {
    bool found = false;
    for (const auto value : known) {
      found = found || value == current;
      gauge(name, help, with(labels, label, std::string(value)), value == current ? 1 : 0);
    }
    if (!found) gauge(name, help, with(labels, label, current), 1);
  }
  // Without bounds nothing is measured there: no series (an empty histogram would claim one).
  void histogram(std::string_view name, std::string_view help, Labels labels, const msg::Histogram& h) {
    if (h.upper_bounds().empty()) return;
    auto& m = sample(name, help, MetricType::Histogram, std::move(labels));
    m.histogram.sample_count = h.count();
    m.histogram.sample_sum = h.sum();
    const auto n = std::min(h.upper_bounds().size(), h.cumulative_counts().size());
    for (std::size_t i = 0; i < n; ++i) m.histogram.bucket.push_back({h.cumulative_counts()[i], h.upper_bounds()[i]});
  }

  std::string text() const {
    std::ostringstream out;
    prometheus::TextSerializer().Serialize(out, families_);
    return out.str();
  }

  static Labels with(Labels labels, std::string_view name, std::string value) {
    labels.push_back({std::string(name), std::move(value)});
    return labels;
  }

 private:
  prometheus::ClientMetric& sample(std::string_view name, std::string_view help, MetricType type, Labels labels) {
    auto it = std::find_if(families_.begin(), families_.end(), [&](const auto& f) { return f.name == name; });
    if (it == families_.end()) {
      families_.push_back({std::string(name), std::string(help), type, {}});
      it = std::prev(families_.end());
    }
    prometheus::ClientMetric m;
    m.label = std::move(labels);
    it->metric.push_back(std::move(m));
    return it->metric.back();
  }

  std::vector<prometheus::MetricFamily> families_;
};

// Label values as Prometheus spells enum values: lower case, words joined by '_'
// ("error-passive" -> "error_passive", "boot failed" -> "boot_failed").
std::string label_value(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    if (c == ' ' || c == '-') {
      if (!out.empty() && out.back() != '_') out.push_back('_');
    } else {
      out.push_back(static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c));
    }
  }
  return out;
}

std::string nmt_state(msg::NmtState s) {
  switch (s) {
    case msg::NMT_BOOT_UP: return "boot_up";
    case msg::NMT_STOPPED: return "stopped";
    case msg::NMT_OPERATIONAL: return "operational";
    case msg::NMT_PRE_OPERATIONAL: return "pre_operational";
    case msg::NMT_UNKNOWN: break;
  }
  return "unknown";
}

// The label sets of the enums (docs/observability.md lists them): CiA 301's NMT states, the
// master's node states (canopen/node_state.hpp and the line's holds) or a monitor's one, the
// controller states of can/bus.hpp.
constexpr std::array<std::string_view, 5> kNmtStates{"unknown", "boot_up", "stopped", "operational", "pre_operational"};
constexpr std::array<std::string_view, 10> kMasterNodeStates{"unknown",
                                                             "booting",
                                                             "boot_failed",
                                                             "running_unmanaged",
                                                             "operational",
                                                             "stopped_by_operator",
                                                             "resetting",
                                                             "lost",
                                                             "waiting_for_a_mandatory_device",
                                                             "stopped_by_the_line"};
// A monitor bus's devices have this one state: the master's ten would be ten zeros per device.
constexpr std::array<std::string_view, 1> kMonitorNodeStates{"monitored"};
constexpr std::array<std::string_view, 6> kBusStates{"unknown",       "error_active", "error_warning",
                                                     "error_passive", "bus_off",      "down"};

void bus_metrics(Exposition& x, const Labels& line, const msg::BusDiagnostics& b) {
  const auto labels = Exposition::with(line, "bus", b.name());
  x.gauge("linebridge_bus_info", "A bus of the line: its interface and the bridge's role on it (always 1).",
          Exposition::with(Exposition::with(labels, "interface", b.interface_uri()), "role", b.role()), 1);
  x.state_set("linebridge_bus_state", "The CAN controller's state: 1 for the current one.", labels, "state", kBusStates,
              label_value(b.state()));
  x.counter("linebridge_bus_frames_received_total",
            "CAN frames read from the bus (rate() of it: frames per second in).", labels,
            static_cast<double>(b.frames_in()));
  x.counter("linebridge_bus_frames_transmitted_total",
            "CAN frames the bridge sent (rate() of it: frames per second out).", labels,
            static_cast<double>(b.frames_out()));
  x.counter("linebridge_bus_error_frames_total", "Error frames the controller reported.", labels,
            static_cast<double>(b.error_frames()));
  x.counter("linebridge_bus_transmit_dropped_total", "Frames the bus refused or could not queue.", labels,
            static_cast<double>(b.tx_dropped()));
  x.counter("linebridge_bus_receive_dropped_total", "Frames the socket's receive queue had no room for.", labels,
            static_cast<double>(b.rx_dropped()));
  x.counter("linebridge_bus_receive_overflows_total", "Controller overflow reports.", labels,
            static_cast<double>(b.rx_overflows()));
  x.counter("linebridge_bus_off_entries_total", "Entries into bus-off.", labels, static_cast<double>(b.bus_offs()));
  x.counter("linebridge_bus_reopens_total", "Times the interface came back and was opened again.", labels,
            static_cast<double>(b.reopens()));
  // CAN's error counters rise with errors and fall with good frames: gauges, whatever their name in
  // the CAN standard (TEC, REC; 128 and up error-passive, a TEC beyond 255 bus-off).
  x.gauge("linebridge_bus_controller_tx_errors",
          "The controller's transmit error counter (TEC), from the last error frame that carried it.", labels,
          b.tx_error_counter());
  x.gauge("linebridge_bus_controller_rx_errors",
          "The controller's receive error counter (REC), from the last error frame that carried it.", labels,
          b.rx_error_counter());
  // A replay at full pace has no load (frames come as fast as they are read): no sample then.
  if (b.load_percent() >= 0) {
    x.gauge("linebridge_bus_load_ratio",
            "Bits on the bus over the last second of the configured bit rate, without bit stuffing (0..1).", labels,
            b.load_percent() / 100.0);
  }
  if (b.sync_period_s() > 0) {
    x.gauge("linebridge_bus_sync_period_seconds", "The period of the SYNC the bridge produces on the bus.", labels,
            b.sync_period_s());
  }
  x.histogram("linebridge_bus_sync_period_deviation_seconds",
              "Per SYNC the bridge produced: |interval from the SYNC before - period|.", labels,
              b.sync_period_deviation_s());
  x.gauge("linebridge_bus_yielding_to_other_master",
          "1 while the bridge sends nothing on the bus because another master is heard.", labels,
          b.yielding_to_other_master() ? 1 : 0);
  x.gauge("linebridge_bus_mandatory_devices_missing", "Mandatory devices that have not passed their boot now.", labels,
          static_cast<double>(b.mandatory_missing().size()));
  x.counter("linebridge_bus_handler_failures_total", "Callbacks of the bus loop that threw (the loop goes on).", labels,
            static_cast<double>(b.handler_failures()));
  x.counter("linebridge_bus_frames_unclaimed_total", "Frames nothing on this bus handles.", labels,
            static_cast<double>(b.frames_unclaimed()));
  x.counter("linebridge_bus_requests_refused_total",
            "Service requests, set values and commands refused: too many already waited for the loop.", labels,
            static_cast<double>(b.requests_refused()));
}

void device_metrics(Exposition& x, const Labels& line, const msg::NodeDiagnostics& n) {
  auto labels = Exposition::with(line, "bus", n.bus());
  labels = Exposition::with(std::move(labels), "device", n.device());
  labels = Exposition::with(std::move(labels), "node", std::to_string(n.node_id()));
  x.gauge("linebridge_device_up", "1 while the device's heartbeat comes within its timeout.", labels,
          n.online() ? 1 : 0);
  x.state_set("linebridge_device_nmt_state", "The device's CiA 301 NMT state as the bridge believes it: 1 for it.",
              labels, "state", kNmtStates, nmt_state(n.nmt_state()));
  const auto node_state = label_value(n.node_state());
  const auto monitored = node_state == kMonitorNodeStates[0];
  x.state_set("linebridge_device_node_state", "The master's state of the device: 1 for the current one.", labels,
              "state",
              monitored ? std::span<const std::string_view>(kMonitorNodeStates)
                        : std::span<const std::string_view>(kMasterNodeStates),
              node_state);
  if (n.last_heartbeat_age_s() >= 0) {
    x.gauge("linebridge_device_last_heartbeat_age_seconds",
            "Time since the device's last heartbeat, as of the newest diagnostics sample.", labels,
            n.last_heartbeat_age_s());
  }
  x.counter("linebridge_device_boot_ups_total", "Boot-up messages of the device.", labels,
            static_cast<double>(n.boot_ups()));
  x.counter("linebridge_device_boots_total", "Boots the bridge began (start-up, boot-ups, lost state, retries).",
            labels, static_cast<double>(n.boots()));
  for (const auto& c : n.boot_failures_by_letter()) {
    x.counter("linebridge_device_boot_failures_total", "Boots that failed, by CiA 302-2 error letter.",
              Exposition::with(labels, "letter", c.name()), static_cast<double>(c.count()));
  }
  for (const auto& c : n.emergencies_by_class()) {
    x.counter("linebridge_device_emergencies_total", "EMCY messages of the device, by class of the error code.",
              Exposition::with(labels, "class", c.name()), static_cast<double>(c.count()));
  }
  x.counter("linebridge_device_pdos_received_total", "PDOs received from the device.", labels,
            static_cast<double>(n.pdos_received()));
  x.counter("linebridge_device_pdos_sent_total", "PDOs the bridge sent to the device.", labels,
            static_cast<double>(n.pdos_sent()));
  x.counter("linebridge_device_pdo_length_errors_total", "PDOs of the device shorter than their mapping.", labels,
            static_cast<double>(n.pdo_length_errors()));
  x.counter("linebridge_device_range_warnings_total", "Values received outside the profile's range.", labels,
            static_cast<double>(n.range_warnings()));
  x.counter("linebridge_device_state_unknown_total",
            "Heartbeats back after a loss, or states the bridge did not command.", labels,
            static_cast<double>(n.state_unknown()));
  x.histogram("linebridge_device_sdo_duration_seconds",
              "The bridge's SDO transfers to the device, from the first frame to the answer, abort or timeout.", labels,
              n.sdo_duration_s());
}

void dds_metrics(Exposition& x, const Labels& line, const LineView& view, const msg::Diagnostics* d) {
  x.gauge("linebridge_dds_side_connected", "1 while this DDS process is let in by its bus process.", line,
          view.connected ? 1 : 0);
  x.counter("linebridge_dds_samples_published_total", "Samples of the bus process this DDS process wrote to DDS.", line,
            static_cast<double>(view.samples_published));
  x.counter("linebridge_dds_samples_not_forwarded_total",
            "Set values and requests from DDS the bus process could not take in time.", line,
            static_cast<double>(view.samples_not_forwarded));
  x.gauge("linebridge_dds_remote_participants", "DDS participants this process knows now.", line,
          view.remote_participants);
  x.counter("linebridge_dds_remote_participants_refused_total",
            "Remote participants refused since this DDS process started (limits, failed authentication).", line,
            static_cast<double>(view.remote_participants_refused));
  x.counter("linebridge_dds_discovery_messages_dropped_total",
            "Discovery messages the discovery gate did not hand to Fast DDS.", line,
            static_cast<double>(view.gate.dropped));
  if (d == nullptr) return;
  const auto& side = d->dds_side();
  x.counter("linebridge_dds_side_connects_total", "DDS processes the bus process let in since it started.", line,
            static_cast<double>(side.connects()));
  x.counter("linebridge_dds_samples_sent_total", "Samples the bus process handed to a DDS process.", line,
            static_cast<double>(side.samples_sent()));
  x.counter("linebridge_dds_samples_replaced_total",
            "State samples a newer one replaced before a DDS process took them.", line,
            static_cast<double>(side.samples_replaced()));
  x.counter("linebridge_dds_samples_dropped_total",
            "Events and answers the bus process dropped: no DDS process, or its queue full.", line,
            static_cast<double>(side.samples_dropped()));
  x.counter("linebridge_dds_side_absent_alarms_total",
            "Times the line was without a DDS process for the alarm's time (--dds-absent-alarm).", line,
            static_cast<double>(side.absent_alarms()));
  x.counter("linebridge_commands_lost_total",
            "Set values and requests clients wrote that never reached the bridge (sequence gaps).", line,
            static_cast<double>(d->commands_lost()));
  x.counter("linebridge_log_lines_dropped_total", "Log lines dropped because the log's queue was full.", line,
            static_cast<double>(d->log_lines_dropped()));
}

}  // namespace

std::string render_metrics(const LineView& view) {
  Exposition x;
  const Labels line{{"line", view.line}};
  x.gauge("linebridge_build_info", "The bridge's version (always 1).",
          Exposition::with(line, "version", std::string(kVersion)), 1);
  const msg::Diagnostics* d = view.diagnostics.get();
  if (d != nullptr) {
    x.gauge("linebridge_diagnostics_age_seconds",
            "Time since the newest diagnostics sample of the bus process arrived (one a second).", line,
            view.diagnostics_age_s());
  }
  dds_metrics(x, line, view, d);
  if (d != nullptr) {
    for (const auto& b : d->buses()) bus_metrics(x, line, b);
    for (const auto& n : d->nodes()) device_metrics(x, line, n);
  }
  return x.text();
}

}  // namespace lb::app::obs
