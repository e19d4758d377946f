#pragma once
// One row's line of the safety table (test_safety_*.cpp): the real bridge and one real simulator
// process per device (linebridge-sim --device NAME) on a virtual bus of their own, so that a
// device can lose power alone (SIGKILL, then started again: it comes back pre-operational with its
// power-on values) or stop answering (SIGSTOP/SIGCONT), and the bridge can be killed and started
// again with the same state_dir and, if the row wants, a changed line file. This test is a passive
// bus member that records every frame with its bus stamp and injects spoofed ones (BusSpy: it
// never records its own), and the operator on DDS (safety_operator.hpp), whose every request is
// logged with the moment it was written, for the judge (safety_judge.hpp).

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/collector.hpp"
#include "support/eventually.hpp"
#include "support/line_views.hpp"
#include "support/safety_device.hpp"
#include "support/safety_judge.hpp"
#include "support/safety_operator.hpp"
#include "support/scratch_files.hpp"
#include "support/spy_waits.hpp"

namespace lb::test::safety {

struct RowOptions {
  int heartbeat_timeout_ms = 400;  // the device's, in the bridge's line file
  int sdo_timeout_ms = 0;          // the bus's; 0: the line file's default
};

struct Spoofed {
  std::int64_t sent_ns;
  lb::can::CanFrame frame;
};

class SafetyLine {
 public:
  SafetyLine(const SafetyDevice& device, RowOptions options)
      : device_(device),
        options_(options),
        row_(next_row()),
        tag_(std::to_string(::getpid()) + "-" + std::to_string(row_)) {
    // Every row its own domain, bus and files: a killed bridge of an earlier row in the same process
    // is still announced for its lease (10 s) and must not match this row's endpoints.
    domain_ = 70 + static_cast<std::uint32_t>(row_ % 100);
    bus_ = "virtual:safety-" + tag_;
    dir_ = ::testing::TempDir() + "/safety_" + device_.column + "_" + tag_;
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_ + "/state");
  }
  ~SafetyLine() {
    panel_.reset();  // DDS entities before the participant they live in
    nmt_.reset();
    diag_.reset();
    dds_.reset();
    if (bridge_) bridge_->stop();
    if (sim_) {
      if (sim_->running()) ::kill(sim_->pid(), SIGCONT);  // a stalled device takes SIGTERM only once resumed
      sim_->stop();
    }
  }
  SafetyLine(const SafetyLine&) = delete;
  SafetyLine& operator=(const SafetyLine&) = delete;

  const SafetyDevice& device() const { return device_; }
  const RowOptions& options() const { return options_; }
  std::int64_t t0() const { return t0_; }

  // The bridge and the device, the operator's panel ready, the device operational; throws (with
  // the logs) when it never gets there.
  void start() {
    if (std::getenv("LINEBRIDGE_NETNS") == nullptr)
      throw std::runtime_error("run through launch_scripts/netns-run.sh (ctest does)");
    write_bridge_config();
    std::ofstream(sim_config()) << head() << "devices:\n"
                                << device_entry() << "    simulation: {heartbeat_period_ms: 100}\n";
    spy_ = std::make_unique<BusSpy>(bus_);  // first member: the hub lives in this process
    t0_ = bus_now_ns();
    start_device();
    // The bridge starts once the device is up (its boot-up), so that its first boot does not race
    // the device's power-on (an SDO request lost before the device listens costs an SDO timeout).
    if (!frame_after(t0_ - 1, [this](const lb::can::CanFrame& f) {
          return f.id == device_.heartbeat_id() && f.len == 1 && f.data[0] == 0;
        }))
      throw std::runtime_error(device_.name + " never booted up\n" + logs());
    start_bridge();
    auto dds = ddsl::Participant::create({domain_, true, "safety-test"});
    if (!dds) throw std::runtime_error(dds.error().message);
    dds_ = std::move(*dds);
    diag_ = std::make_unique<Collector<linebridge_msgs::msg::DiagnosticsPubSubType>>();
    if (auto r = diag_->subscribe(*dds_, ddsl::topic_name(line_, ddsl::kBridgeNamespace, "diagnostics"),
                                  ddsl::QosKind::state);
        !r)
      throw std::runtime_error(r.error().message);
    nmt_ = detail::make_client<NmtClient>(*dds_, ddsl::line_service_path(line_, "nmt"), line_);
    panel_ = make_panel({*dds_, line_, device_});
    if (!wait_node(0, [](const auto& n) { return n.node_state() == "operational"; }))
      throw std::runtime_error(device_.name + " never operational\n" + logs());
    if (!eventually(std::chrono::seconds(30), [&] { return panel_->matches() > 0; }) || !panel_->warm() || !warm_nmt())
      throw std::runtime_error("the operator's set values and services never reached the bridge\n" + logs());
  }

  // ---- the processes ----

  // The bridge's line file: the device as the rows start it, plus `extra` keys under the device
  // (indented by four: identity, pdos). Read at the bridge's next start.
  void write_bridge_config(const std::string& extra = "") {
    std::ofstream(bridge_config()) << head() << "state_dir: " << dir_ << "/state\ndevices:\n"
                                   << device_entry() << extra;
  }
  void start_bridge() {
    logs_.push_back(dir_ + "/bridge_" + std::to_string(logs_.size()) + ".log");
    bridge_runs_.push_back({bus_now_ns()});
    bridge_ = std::make_unique<ChildProcess>(std::vector<std::string>{LB_BIN_BRIDGE, "--config", bridge_config()},
                                             logs_.back());
  }
  void kill_bridge() {
    if (!bridge_runs_.empty() && bridge_runs_.back().ended_ns == 0) bridge_runs_.back().ended_ns = bus_now_ns();
    kill_hard(bridge_);
  }
  // The bridge's bus process runs so far: what it could hear (the judge's "heard").
  const std::vector<BusProcessRun>& bridge_runs() const { return bridge_runs_; }
  void start_device() {
    logs_.push_back(dir_ + "/sim_" + std::to_string(logs_.size()) + ".log");
    sim_ = std::make_unique<ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", sim_config(), "--device",
                                                                   device_.name},
                                          logs_.back());
  }
  // Power lost: nothing of it is left, it comes back with its power-on values.
  void kill_device() { kill_hard(sim_); }
  // Stops answering (its process stopped), and goes on where it was.
  void stall_device() { ::kill(sim_->pid(), SIGSTOP); }
  void resume_device() { ::kill(sim_->pid(), SIGCONT); }
  pid_t device_pid() const { return sim_->pid(); }

  // ---- what the bridge says on DDS ----

  // The newest run of the bridge its diagnostics announced (0: none yet).
  std::uint64_t run() {
    const auto v = diag_->samples();
    return v.empty() ? 0 : v.back().bridge_incarnation();
  }
  // The newest diagnostics of run `run` (0: any) say of the device what `pred` wants.
  bool wait_node(std::uint64_t run, const std::function<bool(const linebridge_msgs::msg::NodeDiagnostics&)>& pred,
                 std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    return diag_->wait(timeout, [&](const std::vector<linebridge_msgs::msg::Diagnostics>& v) {
      for (auto it = v.rbegin(); it != v.rend(); ++it) {
        if (run != 0 && it->bridge_incarnation() != run) continue;
        const auto* n = node_of(*it, device_.name);
        return n != nullptr && pred(*n);
      }
      return false;
    });
  }
  // The device's node in the newest diagnostics, as text for a failure message.
  std::string node_text() {
    const auto v = diag_->samples();
    if (v.empty()) return "(no diagnostics)";
    const auto* n = node_of(v.back(), device_.name);
    if (n == nullptr) return "(no node " + device_.name + ")";
    return "node_state '" + n->node_state() + "', boot_state '" + n->boot_state() + "', boot_error '" +
           n->boot_error().code() + "', set_values_at_start '" + n->set_values_at_start() + "'";
  }
  // A run other than `not_run` announced itself, the set-value writer matched its reader (one more
  // match than `matches_before`) and its services answer: a request written now reaches it.
  bool await_run(std::uint64_t not_run, int matches_before) {
    return diag_->wait(std::chrono::seconds(30),
                       [&](const auto& v) { return !v.empty() && v.back().bridge_incarnation() != not_run; }) &&
           eventually(std::chrono::seconds(30), [&] { return panel_->matches() > matches_before; }) && panel_->warm() &&
           warm_nmt();
  }
  OperatorPanel& panel() { return *panel_; }

  // ---- the operator ----

  OperatorRequest set_enabling(bool on) { return log(panel_->set_enabling(on)); }
  OperatorRequest press_stop() { return log(panel_->press_stop()); }
  OperatorRequest nmt(linebridge_msgs::srv::NmtCommand command) { return log(nmt_request(*nmt_, device_, command)); }
  const std::vector<OperatorRequest>& requests() const { return requests_; }

  // ---- the bus ----

  BusSpy& spy() { return *spy_; }
  const std::vector<Spoofed>& spoofed() const { return spoofed_; }
  void spoof(const lb::can::CanFrame& f) {
    const auto at = bus_now_ns();
    if (auto r = spy_->send(f); !r) throw std::runtime_error("spoofed frame not sent: " + r.error().message);
    spoofed_.push_back({at, f});
  }
  // The bus went on until `ns` (a frame stamped then or later is recorded): everything sent
  // before it is recorded too.
  bool bus_past(std::int64_t ns, std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    return eventually(timeout, [&] {
      const auto frames = spy_->frames();
      return !frames.empty() && frames.back().timestamp_ns >= ns;
    });
  }
  // A frame after `after_ns` that matches.
  bool frame_after(std::int64_t after_ns, const FrameMatch& match,
                   std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    return eventually(timeout, [&] {
      for (const auto& f : spy_->frames()) {
        if (f.timestamp_ns > after_ns && match(f)) return true;
      }
      return false;
    });
  }
  // The newest frame of every enabling RPDO the bridge sent has its level on.
  bool enabling_on_bus() {
    const auto frames = spy_->frames();
    for (const auto& e : device_.enabling) {
      const lb::can::CanFrame* last = nullptr;
      for (const auto& f : frames) {
        if (f.id == e.cob_id) last = &f;
      }
      if (last == nullptr || !e.enabled(*last)) return false;
    }
    return true;
  }
  // What the bridge keeps in its state_dir (every file's content), to tell when it changed.
  std::string kept() const {
    std::string all;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(dir_ + "/state", ec)) {
      all += e.path().filename().string() + "\n" + read_text(e.path().string());
    }
    return all;
  }
  // The kept values changed from `before` (a bridge killed now restarts from the new ones).
  bool kept_changed(const std::string& before) {
    return eventually(std::chrono::seconds(3), [&] { return kept() != before; });
  }

  // The tail of every log of this row's processes, newest last.
  std::string logs(std::size_t lines = 80) const {
    std::string out;
    for (const auto& path : logs_) {
      const auto text = read_text(path);
      std::size_t pos = text.size(), n = 0;
      while (pos > 0 && n <= lines) {
        pos = text.rfind('\n', pos - 1);
        if (pos == std::string::npos) {
          pos = 0;
          break;
        }
        ++n;
      }
      out += "--- " + path + (pos > 0 ? " (tail)" : "") + " ---\n" + text.substr(pos) + "\n";
    }
    return out;
  }

 private:
  static int next_row() {
    static std::atomic<int> rows{0};
    return rows++;
  }
  static void kill_hard(std::unique_ptr<ChildProcess>& p) {
    if (!p || !p->running()) return;
    ::kill(p->pid(), SIGKILL);
    eventually(std::chrono::seconds(10), [&] { return !p->running(); });
  }
  std::string bridge_config() const { return dir_ + "/bridge.yaml"; }
  std::string sim_config() const { return dir_ + "/sim.yaml"; }
  std::string head() const {
    std::string bus = "  - {name: b, interface: '" + bus_ + "'";
    if (options_.sdo_timeout_ms > 0) bus += ", sdo_timeout_ms: " + std::to_string(options_.sdo_timeout_ms);
    return "line: " + line_ + "\ndds:\n  domain: " + std::to_string(domain_) + "\nbuses:\n" + bus + "}\n";
  }
  std::string device_entry() const {
    return "  - name: " + device_.name + "\n    bus: b\n    node_id: " + std::to_string(device_.node) +
           "\n    profile: " + device_.profile + "\n    version: '" + device_.version +
           "'\n    heartbeat_timeout_ms: " + std::to_string(options_.heartbeat_timeout_ms) +
           "\n    boot_retry_ms: 1000\n";
  }
  bool warm_nmt() {
    // A device the line does not have: refused before anything reaches the bus.
    linebridge_msgs::srv::Nmt_Request req;
    req.device("no_such_device");
    req.command(linebridge_msgs::srv::NMT_START);
    return nmt_->call(req, kAnswerDeadline).has_value();
  }
  // An accepted stop is watched for on the bus (bounded) before the operator's next request, so
  // that the next one (an NMT stop) cannot keep it off the bus; the judge times it all the same.
  OperatorRequest log(OperatorRequest r) {
    if (r.stops() && r.accepted) {
      for (const auto& p : r.proofs) (void)frame_after(r.written_ns - 1, p.match, std::chrono::seconds(2));
    }
    requests_.push_back(r);
    return r;
  }

  const SafetyDevice& device_;
  RowOptions options_;
  int row_;
  std::string tag_;
  std::uint32_t domain_ = 70;
  std::string line_ = "safety";
  std::string bus_;
  std::string dir_;
  std::vector<std::string> logs_;
  std::int64_t t0_ = 0;
  std::unique_ptr<BusSpy> spy_;
  std::unique_ptr<ChildProcess> sim_, bridge_;
  std::unique_ptr<ddsl::Participant> dds_;
  std::unique_ptr<Collector<linebridge_msgs::msg::DiagnosticsPubSubType>> diag_;
  std::unique_ptr<NmtClient> nmt_;
  std::unique_ptr<OperatorPanel> panel_;
  std::vector<OperatorRequest> requests_;
  std::vector<Spoofed> spoofed_;
  std::vector<BusProcessRun> bridge_runs_;
};

// Spoofed frames sent on a thread of their own at their offsets from construction (the sleeps
// pace injected traffic), through the line (which logs them), while the test thread acts as the
// operator; joined at destruction.
class Spoofer {
 public:
  using Schedule = std::vector<std::pair<std::chrono::milliseconds, lb::can::CanFrame>>;
  Spoofer(SafetyLine& line, Schedule schedule) : schedule_(std::move(schedule)) {
    thread_ = std::thread([this, &line] {
      const auto start = std::chrono::steady_clock::now();
      for (const auto& [offset, frame] : schedule_) {
        {
          std::unique_lock lock(m_);
          if (cv_.wait_until(lock, start + offset, [this] { return stop_; })) return;
        }
        line.spoof(frame);
        ++sent_;
      }
    });
  }
  ~Spoofer() {
    {
      std::lock_guard lock(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  Spoofer(const Spoofer&) = delete;
  Spoofer& operator=(const Spoofer&) = delete;

  // At least n frames sent (false after the deadline).
  bool sent(std::size_t n, std::chrono::milliseconds timeout = std::chrono::seconds(60)) {
    return eventually(timeout, [&] { return sent_ >= n; });
  }
  bool done(std::chrono::milliseconds timeout = std::chrono::seconds(60)) { return sent(schedule_.size(), timeout); }

 private:
  Schedule schedule_;
  std::atomic<std::size_t> sent_{0};
  std::mutex m_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace lb::test::safety
