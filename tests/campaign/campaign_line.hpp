#pragma once
// The fault campaign's line (issue 40, point 6): one device of every registered type as the safety
// table knows them (support/safety_device.hpp), each played by a linebridge-sim process of its own
// so that each can lose power alone, five on one bus and the feeder box on a second, served by one
// real bridge (linebridge, --part both by default: its bus process starts its DDS process). The
// campaign is a passive member of both buses (BusSpy: it records every frame with its bus stamp and
// injects spoofed ones, which it never records) and a DDS participant: the operators' panels (one
// each, campaign_operator.hpp), a probe that tells when the bridge answers again, and two
// linebridge-cli echo processes, DDS clients of the line that a fault can stall.
//
// What the harness does to the bridge's processes is kept for the judge (safety_judge.hpp): the
// runs of the bus process (what it could hear) and the outages (from a kill or stop of one of its
// processes until the probe is answered again).

#include <dirent.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
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
#include "support/spy_waits.hpp"

namespace lb::test::campaign {

using safety::BridgeTimeline;
using safety::BusProcessRun;
using safety::Outage;
using safety::SafetyDevice;

// A device of the line: the table's column under a name of its own, and its bus.
struct CampaignDevice {
  SafetyDevice device;
  std::string bus;  // "extrusion" or "weaving"
};

// A spoofed frame as it was sent (the spies never record their own).
struct SpoofedFrame {
  std::string bus;
  lb::can::CanFrame frame;  // stamped with the moment it was sent
};

struct CampaignOptions {
  std::string dir;  // the line's files, state_dir and every process's log
  std::uint32_t domain = 90;
  int heartbeat_timeout_ms = 500;
};

class CampaignLine {
 public:
  static constexpr const char* kLine = "campaign";

  CampaignLine(std::vector<CampaignDevice> devices, CampaignOptions options)
      : devices_(std::move(devices)), options_(std::move(options)), tag_(std::to_string(::getpid())) {
    std::filesystem::remove_all(options_.dir);
    std::filesystem::create_directories(options_.dir + "/state");
    sims_.resize(devices_.size());
  }
  ~CampaignLine() {
    stop_watch();
    probe_.reset();  // DDS entities before the participant they live in
    diag_.reset();
    for (auto& c : clients_) {
      if (c->running()) ::kill(c->pid(), SIGCONT);  // a stalled process takes SIGTERM once resumed
    }
    clients_.clear();
    if (bridge_) bridge_->stop();
    for (auto& sim : sims_) {
      if (sim && sim->running()) ::kill(sim->pid(), SIGCONT);  // a stalled process takes SIGTERM once resumed
    }
    sims_.clear();
  }
  CampaignLine(const CampaignLine&) = delete;
  CampaignLine& operator=(const CampaignLine&) = delete;

  const std::vector<CampaignDevice>& devices() const { return devices_; }
  const CampaignOptions& options() const { return options_; }
  std::int64_t t0() const { return t0_; }
  std::string line() const { return kLine; }
  std::vector<std::string> buses() const { return {"extrusion", "weaving"}; }

  // Every device up, the bridge serving it (every node operational), the clients started and the
  // bridge answering; throws (with the logs) when it never gets there.
  void start() {
    if (std::getenv("LINEBRIDGE_NETNS") == nullptr)
      throw std::runtime_error("run through launch_scripts/netns-run.sh (the script and ctest do)");
    write_configs();
    for (const auto& bus : buses()) spies_[bus] = std::make_unique<BusSpy>(interface(bus));  // the hubs live here
    t0_ = bus_now_ns();
    for (std::size_t i = 0; i < devices_.size(); ++i) power_on(i);
    // The bridge starts once every device is up (its boot-up), so that its first boot does not race
    // a device's power-on.
    for (std::size_t i = 0; i < devices_.size(); ++i) {
      const auto& d = devices_[i];
      if (!eventually(std::chrono::seconds(30), [&] {
            for (const auto& f : spies_.at(d.bus)->frames(d.device.heartbeat_id())) {
              if (f.len == 1 && f.data[0] == 0) return true;
            }
            return false;
          }))
        throw std::runtime_error(d.device.name + " never booted up\n" + logs());
    }
    start_bus_process();
    auto dds = ddsl::Participant::create({options_.domain, true, "fault-campaign"});
    if (!dds) throw std::runtime_error(dds.error().message);
    dds_ = std::move(*dds);
    diag_ = std::make_unique<Collector<linebridge_msgs::msg::DiagnosticsPubSubType>>();
    if (auto r = diag_->subscribe(*dds_, ddsl::topic_name(kLine, ddsl::kBridgeNamespace, "diagnostics"),
                                  ddsl::QosKind::state);
        !r)
      throw std::runtime_error(r.error().message);
    probe_ = safety::detail::make_client<safety::NmtClient>(*dds_, ddsl::line_service_path(kLine, "nmt"), kLine);
    if (!eventually(std::chrono::seconds(60), [&] { return all_operational(); }))
      throw std::runtime_error("the devices never were all operational\n" + logs());
    if (!probe(std::chrono::seconds(30))) throw std::runtime_error("the bridge never answered\n" + logs());
    // DDS clients of the line that a fault can stall: a reader of a saw's status (a state topic,
    // 10 samples a second) and one of the bridge's diagnostics.
    start_client({"echo", devices_.front().device.name, "status"});
    start_client({"echo", "bridge", "diagnostics"});
    watch_ = std::thread([this] { watch(); });
  }

  // ---- the devices ----

  // Power on: a simulator process of its own, which boots up with its power-on values.
  void power_on(std::size_t i) {
    logs_.push_back(options_.dir + "/sim_" + devices_[i].device.name + "_" + std::to_string(logs_.size()) + ".log");
    sims_[i] = std::make_unique<ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", sim_config(), "--device",
                                                                       devices_[i].device.name},
                                              logs_.back());
  }
  // Power lost: nothing of the device is left.
  void power_off(std::size_t i) { kill_hard(sims_[i]); }
  // Stops answering (its process stopped), and goes on where it was.
  void stall_device(std::size_t i) {
    if (sims_[i] && sims_[i]->running()) ::kill(sims_[i]->pid(), SIGSTOP);
  }
  void resume_device(std::size_t i) {
    if (sims_[i] && sims_[i]->running()) ::kill(sims_[i]->pid(), SIGCONT);
  }

  // ---- the bridge ----

  void start_bus_process() {
    logs_.push_back(options_.dir + "/bridge_" + std::to_string(logs_.size()) + ".log");
    {
      std::lock_guard lock(m_);
      timeline_.runs.push_back({bus_now_ns()});
      answers_after_ns_ = timeline_.runs.back().started_ns;
    }
    bridge_ = std::make_unique<ChildProcess>(std::vector<std::string>{LB_BIN_BRIDGE, "--config", bridge_config()},
                                             logs_.back());
  }
  // kill -9 of the bus process (its DDS process dies with it, PR_SET_PDEATHSIG); start_bus_process()
  // brings it back, as the service manager would.
  void kill_bus_process() {
    ended("the bus process killed (kill -9)");
    kill_hard(bridge_);
  }
  // A restart: SIGTERM (a clean stop), then started again.
  void restart_bridge() {
    ended("a bridge restart (SIGTERM, started again)");
    if (bridge_) bridge_->stop();
    start_bus_process();
  }
  // kill -9 of the DDS process: its bus process starts another. False when there is none to kill.
  bool kill_dds_process() {
    if (!bridge_ || !bridge_->running()) return false;
    const auto children = children_of(bridge_->pid());
    if (children.size() != 1) return false;
    open_outage("the DDS process killed (kill -9)");
    return ::kill(children.front(), SIGKILL) == 0;
  }
  bool bridge_running() { return bridge_ && bridge_->running(); }

  // ---- DDS clients a fault stalls ----

  std::size_t clients() const { return clients_.size(); }
  std::string client_what(std::size_t k) const { return client_what_[k]; }
  void stall_client(std::size_t k) {
    if (clients_[k]->running()) ::kill(clients_[k]->pid(), SIGSTOP);
  }
  void resume_client(std::size_t k) {
    if (clients_[k]->running()) ::kill(clients_[k]->pid(), SIGCONT);
  }

  // ---- the buses ----

  void spoof(const std::string& bus, lb::can::CanFrame f) {
    f.timestamp_ns = bus_now_ns();
    if (auto r = spies_.at(bus)->send(f); !r) throw std::runtime_error("spoofed frame not sent: " + r.error().message);
    std::lock_guard lock(m_);
    spoofed_.push_back({bus, f});
  }
  // Every frame recorded on the bus, in the order of their stamps.
  std::vector<lb::can::CanFrame> frames(const std::string& bus) { return safety::by_stamp(spies_.at(bus)->frames()); }
  std::vector<SpoofedFrame> spoofed() {
    std::lock_guard lock(m_);
    return spoofed_;
  }
  BridgeTimeline timeline() {
    std::lock_guard lock(m_);
    return timeline_;
  }

  // ---- DDS ----

  ddsl::Participant& dds() { return *dds_; }
  // The bridge answers (a harmless NMT request: a device the line does not have, refused before
  // anything reaches the bus) within the timeout.
  bool probe(std::chrono::milliseconds timeout) {
    linebridge_msgs::srv::Nmt_Request req;
    req.device("no_such_device");
    req.command(linebridge_msgs::srv::NMT_START);
    return probe_->call(req, timeout).has_value();
  }
  // The newest diagnostics say every device is operational.
  bool all_operational() {
    const auto v = diag_->samples();
    if (v.empty()) return false;
    for (const auto& d : devices_) {
      const auto* n = node_of(v.back(), d.device.name);
      if (n == nullptr || n->node_state() != "operational") return false;
    }
    return true;
  }

  // The tail of every log, newest last.
  std::string logs(std::size_t lines = 40) const {
    std::string out;
    for (const auto& path : logs_) {
      std::ifstream in(path);
      std::vector<std::string> all;
      for (std::string l; std::getline(in, l);) all.push_back(l);
      out += "--- " + path + " ---\n";
      for (std::size_t i = all.size() > lines ? all.size() - lines : 0; i < all.size(); ++i) out += all[i] + "\n";
    }
    return out;
  }

 private:
  static void kill_hard(std::unique_ptr<ChildProcess>& p) {
    if (!p || !p->running()) return;
    ::kill(p->pid(), SIGCONT);
    ::kill(p->pid(), SIGKILL);
    eventually(std::chrono::seconds(10), [&] { return !p->running(); });
  }

  // The bus process ends now (the kill or stop is sent next): what it hears ends, an outage begins.
  void ended(const std::string& what) {
    {
      std::lock_guard lock(m_);
      if (!timeline_.runs.empty() && timeline_.runs.back().ended_ns == 0) timeline_.runs.back().ended_ns = bus_now_ns();
      // A process told to stop may still answer while it stops: only the next one's answer counts.
      answers_after_ns_ = std::numeric_limits<std::int64_t>::max();
    }
    open_outage(what);
  }
  void open_outage(const std::string& what) {
    std::lock_guard lock(m_);
    answers_after_ns_ = std::max(answers_after_ns_, bus_now_ns());
    if (!timeline_.outages.empty() && timeline_.outages.back().back_ns == 0) {
      timeline_.outages.back().what += " and " + what;  // one outage until the bridge answers again
      return;
    }
    timeline_.outages.push_back({bus_now_ns(), 0, what});
  }
  // The probe's thread: an open outage ends when the bridge answers again.
  void watch() {
    while (!stopping_) {
      bool open = false;
      {
        std::lock_guard lock(m_);
        open = !timeline_.outages.empty() && timeline_.outages.back().back_ns == 0;
      }
      if (open) {
        const auto asked = bus_now_ns();
        if (probe(std::chrono::seconds(2))) {
          std::lock_guard lock(m_);
          // Only an answer to a request asked of the processes that came back (not of one still
          // stopping, not before a fault that came while asking) ends the outage.
          auto& o = timeline_.outages.back();
          if (o.back_ns == 0 && asked > answers_after_ns_) o.back_ns = bus_now_ns();
        }
        continue;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  void stop_watch() {
    stopping_ = true;
    if (watch_.joinable()) watch_.join();
  }

  void start_client(std::vector<std::string> args) {
    std::vector<std::string> argv{LB_BIN_CLI, "--config", bridge_config()};
    std::string what = "linebridge-cli";
    for (auto& a : args) {
      what += " " + a;
      argv.push_back(std::move(a));
    }
    logs_.push_back(options_.dir + "/client_" + std::to_string(clients_.size()) + ".log");
    clients_.push_back(std::make_unique<ChildProcess>(std::move(argv), logs_.back()));
    client_what_.push_back(what);
  }

  std::string interface(const std::string& bus) const { return "virtual:campaign-" + bus + "-" + tag_; }
  std::string bridge_config() const { return options_.dir + "/bridge.yaml"; }
  std::string sim_config() const { return options_.dir + "/sim.yaml"; }
  std::string head() const {
    std::string s = std::string("line: ") + kLine + "\ndds:\n  domain: " + std::to_string(options_.domain) +
                    "\nbuses:\n";
    for (const auto& bus : buses()) s += "  - {name: " + bus + ", interface: '" + interface(bus) + "'}\n";
    return s;
  }
  std::string entry(const CampaignDevice& d) const {
    return "  - name: " + d.device.name + "\n    bus: " + d.bus + "\n    node_id: " + std::to_string(d.device.node) +
           "\n    profile: " + d.device.profile + "\n    version: '" + d.device.version +
           "'\n    heartbeat_timeout_ms: " + std::to_string(options_.heartbeat_timeout_ms) +
           "\n    boot_retry_ms: 1000\n";
  }
  void write_configs() const {
    std::ofstream bridge(bridge_config());
    bridge << head() << "state_dir: " << options_.dir << "/state\ndevices:\n";
    for (const auto& d : devices_) bridge << entry(d);
    std::ofstream sim(sim_config());
    sim << head() << "devices:\n";
    for (const auto& d : devices_) sim << entry(d) << "    simulation: {heartbeat_period_ms: 100}\n";
  }

  std::vector<CampaignDevice> devices_;
  CampaignOptions options_;
  std::string tag_;
  std::int64_t t0_ = 0;
  std::vector<std::string> logs_;
  std::map<std::string, std::unique_ptr<BusSpy>> spies_;
  std::vector<std::unique_ptr<ChildProcess>> sims_;
  std::unique_ptr<ChildProcess> bridge_;
  std::vector<std::unique_ptr<ChildProcess>> clients_;
  std::vector<std::string> client_what_;
  std::unique_ptr<ddsl::Participant> dds_;
  std::unique_ptr<Collector<linebridge_msgs::msg::DiagnosticsPubSubType>> diag_;
  std::unique_ptr<safety::NmtClient> probe_;
  std::mutex m_;  // timeline_, spoofed_
  BridgeTimeline timeline_;
  std::int64_t answers_after_ns_ = 0;  // the probe's answers to requests asked later end an outage
  std::vector<SpoofedFrame> spoofed_;
  std::atomic<bool> stopping_{false};
  std::thread watch_;
};

}  // namespace lb::test::campaign
