#pragma once
// One line under test: the real linebridge and linebridge-sim processes on a virtual bus of their
// own, this test as a passive bus member (BusSpy, which also injects frames) and as a DDS
// participant with clients for the line-wide services. The bridge and the simulator may read
// different files: a device and the master's view of it are two things (a wrong device at a
// node-ID, a device whose factory configuration differs from the profile).

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/routing/bridge_runs.hpp"
#include "msgs/commonPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/collector.hpp"
#include "support/eventually.hpp"
#include "support/line_views.hpp"

namespace lb::test {

class LineHarness {
 public:
  using ReadClient = ddsl::ServiceClient<linebridge_msgs::srv::SdoRead_RequestPubSubType,
                                         linebridge_msgs::srv::SdoRead_ResponsePubSubType>;
  using WriteClient = ddsl::ServiceClient<linebridge_msgs::srv::SdoWrite_RequestPubSubType,
                                          linebridge_msgs::srv::SdoWrite_ResponsePubSubType>;
  using NmtClient =
      ddsl::ServiceClient<linebridge_msgs::srv::Nmt_RequestPubSubType, linebridge_msgs::srv::Nmt_ResponsePubSubType>;
  using CommandClient = ddsl::ServiceClient<linebridge_msgs::srv::Command_RequestPubSubType,
                                            linebridge_msgs::srv::Command_ResponsePubSubType>;

  // name: the line (and the files' prefix); the bus is virtual:<name>-<pid>.
  LineHarness(std::string name, std::uint32_t domain)
      : name_(std::move(name)),
        domain_(domain),
        tag_(std::to_string(::getpid())),
        bus_("virtual:" + name_ + "-" + tag_) {}

  ~LineHarness() {
    reads_.reset();  // clients before the participant they live in
    writes_.reset();
    nmts_.reset();
    commands_.reset();
    dds_.reset();
    if (bridge_) bridge_->stop();
    if (sim_) sim_->stop();
  }

  const std::string& bus() const { return bus_; }
  const std::string& line() const { return name_; }
  std::string topic(const std::string& device, const std::string& t) const {
    return ddsl::topic_name(name_, device, t);
  }

  // `devices` is the YAML of the devices: list (indented by two); the bridge and the simulator
  // read the same file unless `sim_devices` gives the simulator its own.
  // line_keys: top-level keys of the line file (e.g. "state_dir: /tmp/x\n").
  void start(const std::string& devices, const std::string& sim_devices = "", const std::string& bus_keys = "",
             const std::string& line_keys = "") {
    // Every DDS participant of a test lives in a network namespace of its own (ctest wraps each
    // test so): never on the machine's own network.
    if (std::getenv("LINEBRIDGE_NETNS") == nullptr)
      throw std::runtime_error("run through launch_scripts/netns-run.sh (ctest does)");
    const auto dir = ::testing::TempDir();
    const auto write = [&](const std::string& who, const std::string& devs) {
      const auto path = dir + "/" + name_ + "_" + who + "_" + tag_ + ".yaml";
      std::ofstream(path) << "line: " << name_ << "\n"
                          << line_keys << "dds:\n  domain: " << domain_ << "\n"
                          << dds_keys_ << "buses:\n  - {name: b, interface: '" << bus_ << "'" << bus_keys
                          << "}\ndevices:\n"
                          << devs;
      return path;
    };
    bridge_config_ = write("bridge", devices);
    sim_config_ = sim_devices.empty() ? bridge_config_ : write("sim", sim_devices);
    spy_ = std::make_unique<BusSpy>(bus_);  // first member: the hub lives in this process
    start_sim();
    start_bridge();
    ddsl::ParticipantOptions options{domain_, true, name_ + "-test"};
    if (participant_options_) options = *participant_options_;
    auto dds = ddsl::Participant::create(options);
    if (!dds) throw std::runtime_error(dds.error().message);
    dds_ = std::move(*dds);
  }

  // Again after a kill: the devices power up anew.
  void start_sim() {
    sim_ = std::make_unique<ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", sim_config_},
                                          ::testing::TempDir() + "/" + name_ + "_sim_" + tag_ + ".log");
  }

  void start_bridge() {
    auto argv = bridge_launcher_;
    argv.insert(argv.end(), {LB_BIN_BRIDGE, "--config", bridge_config_});
    bridge_ = std::make_unique<ChildProcess>(std::move(argv),
                                             ::testing::TempDir() + "/" + name_ + "_bridge_" + tag_ + ".log");
  }
  // Before start(): more keys of the line file's dds: block, indented by two (a secured line's
  // "  security:\n    ...", TestPki::security_yaml()).
  void set_dds_keys(std::string yaml) { dds_keys_ = std::move(yaml); }
  // Before start(): this test's participant with these options (a secured line's identity)
  // instead of an unsecured one on the line's domain.
  void set_participant_options(ddsl::ParticipantOptions options) { participant_options_ = std::move(options); }
  // Before start(): the bridge is started through this command (an absolute path and its
  // arguments, e.g. setpriv to take a capability away), which must exec it.
  void set_bridge_launcher(std::vector<std::string> argv) { bridge_launcher_ = std::move(argv); }

  // Every sample of a device's topic from now on (throws when the subscription fails, so a test
  // fails there as it does on a failed service call).
  template <class PubSubType>
  Collector<PubSubType> collect(const std::string& device, const std::string& t, ddsl::QosKind kind) {
    Collector<PubSubType> c;
    if (auto r = c.subscribe(*dds_, topic(device, t), kind); !r)
      throw std::runtime_error(topic(device, t) + ": " + r.error().message);
    return c;
  }

  // A device's status, once it says online and operational (throws with the logs when it never
  // does): where most tests start.
  template <class StatusPubSubType>
  Collector<StatusPubSubType> operational_status(const std::string& device,
                                                 std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    auto status = collect<StatusPubSubType>(device, "status", ddsl::QosKind::state);
    if (!status.wait_last(timeout, operational<typename StatusPubSubType::type>))
      throw std::runtime_error(device + " never operational\n" + logs());
    return status;
  }

  const std::string& bridge_config() const { return bridge_config_; }
  bool started() const { return bridge_ != nullptr; }
  BusSpy& spy() { return *spy_; }
  ddsl::Participant& dds() { return *dds_; }
  ChildProcess& bridge() { return *bridge_; }
  ChildProcess& sim() { return *sim_; }
  std::string logs() const {
    return "--- bridge log ---\n" + (bridge_ ? bridge_->log() : "") + "--- sim log ---\n" + (sim_ ? sim_->log() : "");
  }

  template <class Client, class Request>
  auto call(std::unique_ptr<Client>& slot, const std::string& service, Request request) {
    if (!slot) {
      auto c = Client::create(*dds_, ddsl::line_service_path(name_, service), gateways::bridge_runs(name_));
      if (!c) throw std::runtime_error(c.error().message);
      slot = std::move(*c);
    }
    auto r = slot->call(request, std::chrono::seconds(20));
    if (!r) throw std::runtime_error(service + ": " + r.error().message);
    return *r;
  }
  linebridge_msgs::srv::SdoRead_Response sdo_read(const std::string& device, std::uint16_t index, std::uint8_t sub,
                                                  const std::string& type) {
    linebridge_msgs::srv::SdoRead_Request req;
    req.device(device);
    req.index(index);
    req.sub_index(sub);
    req.data_type(type);
    return call(reads_, "sdo_read", req);
  }
  std::uint64_t read_unsigned(const std::string& device, std::uint16_t index, std::uint8_t sub,
                              const std::string& type) {
    const auto r = sdo_read(device, index, sub, type);
    if (!r.success()) throw std::runtime_error(r.message());
    return r.value().unsigned_value();
  }
  linebridge_msgs::srv::SdoWrite_Response sdo_write(const std::string& device, std::uint16_t index, std::uint8_t sub,
                                                    const std::string& type, std::uint64_t value) {
    linebridge_msgs::srv::SdoWrite_Request req;
    req.device(device);
    req.index(index);
    req.sub_index(sub);
    req.value().data_type(type);
    req.value().unsigned_value(value);
    return call(writes_, "sdo_write", req);
  }
  linebridge_msgs::srv::Nmt_Response nmt(const std::string& device, linebridge_msgs::srv::NmtCommand c) {
    linebridge_msgs::srv::Nmt_Request req;
    req.device(device);
    req.command(c);
    return call(nmts_, "nmt", req);
  }
  linebridge_msgs::srv::Command_Response command(const std::string& device, const std::string& name) {
    linebridge_msgs::srv::Command_Request req;
    req.device(device);
    req.command(name);
    return call(commands_, "command", req);
  }

  // Waits until a set-value writer is matched with the bridge's reader and the bridge's writer of
  // `result_topic` with this test's reader: a set value written then is read and answered.
  template <class Writer>
  bool wait_matched(Writer& writer, const std::string& result_topic,
                    std::chrono::steady_clock::duration timeout = std::chrono::seconds(30)) {
    return eventually(timeout, [&] { return writer.matched() != 0 && dds_->matched_writers(result_topic) != 0; });
  }

  // Counts the times `text` appears in the bridge's log.
  std::size_t bridge_log_count(const std::string& text) const {
    const auto log = bridge_->log();
    std::size_t n = 0;
    for (auto pos = log.find(text); pos != std::string::npos; pos = log.find(text, pos + 1)) ++n;
    return n;
  }

 private:
  std::string name_;
  std::uint32_t domain_;
  std::string tag_;
  std::string bus_;
  std::string bridge_config_, sim_config_;
  std::vector<std::string> bridge_launcher_;
  std::string dds_keys_;
  std::optional<ddsl::ParticipantOptions> participant_options_;
  std::unique_ptr<BusSpy> spy_;
  std::unique_ptr<ChildProcess> sim_, bridge_;
  std::unique_ptr<ddsl::Participant> dds_;
  std::unique_ptr<ReadClient> reads_;
  std::unique_ptr<WriteClient> writes_;
  std::unique_ptr<NmtClient> nmts_;
  std::unique_ptr<CommandClient> commands_;
};

}  // namespace lb::test
