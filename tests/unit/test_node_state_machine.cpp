// NodeStateMachine on a scripted bus: no DDS, no processes. The device is a real SDO server on a
// virtual bus plus a script of its NMT behaviour (it takes the master's NMT commands as CiA 301
// says, sends its heartbeat every 50 ms, and can be told to fall silent, drop a boot-up or report
// a state nobody commanded). Every transition of the master's view is checked as the drivers
// hear it (NodeDriver::on_state), and what the master did as frames on the bus.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/node_state_machine.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sdo_server.hpp"
#include "support/bus_spy.hpp"
#include "support/sdo_frames.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;
using co::NodeState;

namespace {

constexpr std::uint8_t kNode = 9;
constexpr std::uint8_t kStart = 0x01, kStop = 0x02, kPreOp = 0x80, kResetNode = 0x81;  // CiA 301 NMT command specifiers
constexpr std::uint8_t kBootUp = 0x00, kStopped = 0x04, kOperational = 0x05,
                       kPreOperational = 0x7F;  // heartbeat states

co::ObjectDictionary device_dictionary() {
  co::ObjectDictionary od;
  const auto add = [&](std::uint16_t index, std::uint8_t sub, co::DataType type, std::vector<std::uint8_t> value) {
    if (auto r = od.add(index, sub, type, co::ObjectAccess::ro, std::move(value)); !r)
      throw std::runtime_error(r.error().message);
  };
  add(0x1000, 0, co::DataType::unsigned32, {0xA4, 0x01, 0x00, 0x00});  // profile 420 (1A4h)
  add(0x1018, 1, co::DataType::unsigned32, {0x34, 0x12, 0x00, 0x00});  // vendor-ID 1234h
  add(0x1018, 2, co::DataType::unsigned32, {0x01, 0x00, 0x00, 0x00});
  add(0x1018, 3, co::DataType::unsigned32, {0x02, 0x00, 0x00, 0x00});
  add(0x1018, 4, co::DataType::unsigned32, {0x03, 0x00, 0x00, 0x00});
  return od;
}

// The device: CiA 301 NMT slave behaviour on its own loop, steered by the test.
class ScriptedDevice {
 public:
  ScriptedDevice(const std::string& uri, std::uint8_t initial_state, bool silent)
      : loop_(lb::can::open_bus(uri).value()),
        server_(loop_, kNode, device_dictionary()),
        state_(initial_state),
        silent_(silent) {
    loop_.on_frame(0x000, [this](const lb::can::CanFrame& f) {
      if (f.len != 2 || (f.data[1] != kNode && f.data[1] != 0)) return;
      switch (f.data[0]) {
        case kStart: state_ = kOperational; break;
        case kStop: state_ = kStopped; break;
        case kPreOp: state_ = kPreOperational; break;
        default:  // reset node / communication: a boot-up, then pre-operational
          state_ = kPreOperational;
          if (drop_boot_up_) {
            drop_boot_up_ = false;
          } else {
            send(kBootUp);
          }
      }
    });
    const auto timer = loop_.create_timer([this] {
      if (!silent_) send(state_);
    });
    loop_.arm_timer(timer, 50ms, 50ms);
    loop_.start();
  }
  ~ScriptedDevice() { loop_.stop(); }

  void silence(bool silent) {
    on_loop([this, silent] { silent_ = silent; });
  }
  void drop_next_boot_up() {
    on_loop([this] { drop_boot_up_ = true; });
  }
  // A state nobody commanded (a local reset whose boot-up was lost, a service tool).
  void report(std::uint8_t state) {
    on_loop([this, state] { state_ = state; });
  }
  // A power cycle: the boot-up, then pre-operational.
  void power_cycle() {
    on_loop([this] {
      state_ = kPreOperational;
      send(kBootUp);
    });
  }
  std::uint8_t state() {
    std::promise<std::uint8_t> p;
    auto f = p.get_future();
    loop_.post([&] { p.set_value(state_); });
    return f.get();
  }

 private:
  void send(std::uint8_t state) { (void)loop_.send(lb::can::make_frame(0x700 + kNode, {state})); }
  template <class F>
  void on_loop(F f) {
    std::promise<void> p;
    auto done = p.get_future();
    loop_.post([&] {
      f();
      p.set_value();
    });
    done.wait();
  }

  co::BusLoop loop_;
  co::SdoServer server_;
  std::uint8_t state_;
  bool silent_;
  bool drop_boot_up_ = false;
};

// What a gateway plugged into the node hears of the state machine.
class Recorder final : public co::NodeDriver {
 public:
  void on_state(NodeState s) noexcept override {
    std::function<void(NodeState)> hook;
    {
      std::lock_guard lock(m_);
      states_.push_back(s);
      hook = hook_;
    }
    if (hook) hook(s);
  }
  // Called on the master's loop thread at every transition, as it is entered.
  void on_every_state(std::function<void(NodeState)> hook) {
    std::lock_guard lock(m_);
    hook_ = std::move(hook);
  }
  void on_boot(const co::BootReport& r) noexcept override {
    std::lock_guard lock(m_);
    boots_.push_back(r);
  }
  std::vector<NodeState> states() {
    std::lock_guard lock(m_);
    return states_;
  }
  std::vector<co::BootReport> boots() {
    std::lock_guard lock(m_);
    return boots_;
  }

 private:
  std::mutex m_;
  std::vector<NodeState> states_;
  std::vector<co::BootReport> boots_;
  std::function<void(NodeState)> hook_;
};

class NodeStateMachineTest : public ::testing::Test {
 protected:
  void SetUp() override {
    uri_ = "virtual:nsm-" + std::to_string(::getpid()) + "-" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
  }
  void TearDown() override {
    if (master_) master_->stop();
    // The SDO client completes what is pending as it goes (a boot's read): while the boot that
    // asked is still there, as LineBridge's destructor does it.
    sdo_.reset();
  }

  // The master side: heartbeat timeout 300 ms, retry 300 ms, reset bound 600 ms, a storm is 3
  // boot-ups within 10 s.
  // hold: an operator's or the line's hold the node has before its first boot (kept from before a
  // restart of the bridge).
  // standby: the machine is not started (take_over() below stands for a standby's takeover).
  void start_master(std::uint8_t device_state, std::optional<std::uint32_t> vendor = 0x1234, bool silent = false,
                    std::optional<co::NmtCommand> hold = std::nullopt, bool standby = false) {
    spy_ = std::make_unique<lb::test::BusSpy>(uri_);
    device_ = std::make_unique<ScriptedDevice>(uri_, device_state, silent);
    master_ = std::make_unique<co::BusLoop>(lb::can::open_bus(uri_).value());
    sdo_ = std::make_unique<co::SdoClient>(*master_);
    node_ = std::make_unique<co::RemoteNode>(*master_, kNode, 300ms, true);
    co::BootSequence::Settings boot;
    boot.identity.profile_number = 0x1A4;
    boot.identity.vendor_id = vendor;
    co::NodeStateMachine::Settings settings;
    settings.retry = 300ms;
    settings.reset_bound = 600ms;
    settings.storm_count = 3;
    settings.storm_window = 10s;
    settings.max_backoff = 60s;
    machine_ = std::make_unique<co::NodeStateMachine>(*master_, *node_, *sdo_, boot, settings);
    node_->attach(recorder_);
    if (hold) node_->hold(*hold);
    master_->start();
    if (!standby) master_->post([this] { machine_->start(); });
  }

  // A standby's takeover, as LineBridge does it: once the device is heard, take_over with the
  // master's last NMT command to it; then the bus's first SYNC reaches the node's drivers.
  ::testing::AssertionResult take_over(std::optional<co::NmtCommand> last_command) {
    if (!eventually([&] { return on_master<bool>([this] { return node_->online(); }); }))
      return ::testing::AssertionFailure() << "the device was never heard";
    on_master<bool>([this, last_command] {
      machine_->take_over(last_command);
      node_->tell([](co::NodeDriver& d) { d.on_sync(); });
      return true;
    });
    return ::testing::AssertionSuccess();
  }
  std::string detail() {
    return on_master<std::string>([this] { return machine_->detail(); });
  }
  // The first report the drivers were told (a boot's or an adoption's), once there is one.
  std::optional<co::BootReport> first_report() {
    if (!eventually([&] { return !recorder_.boots().empty(); })) return std::nullopt;
    return recorder_.boots().front();
  }
  // Every SDO request to the node so far was an upload or an abort (CiA 301 ccs 2, 3, 4: no
  // download, ccs 0 or 1); how many there were. Asked once the reading is over: when the spy has
  // seen an answer (580h + node) to every request (and at least `min` of them), it has seen them all.
  std::size_t sdo_uploads_only(std::size_t min) {
    const auto count = [](const std::vector<lb::can::CanFrame>& all, std::uint32_t id) {
      return static_cast<std::size_t>(
          std::count_if(all.begin(), all.end(), [id](const auto& f) { return f.id == id; }));
    };
    EXPECT_TRUE(spy_->wait_until([&](const auto& all) {
      const auto requests = count(all, 0x600u + kNode);
      return requests >= min && count(all, 0x580u + kNode) == requests;
    })) << "the spy never saw the reading's frames";
    std::size_t n = 0;
    for (const auto& f : spy_->frames(0x600u + kNode)) {
      ++n;
      EXPECT_FALSE(lb::test::sdo_download(f))
          << "an SDO download to an adopted device: command byte " << int(f.data[0]);
    }
    return n;
  }

  template <class T, class F>
  T on_master(F f) {
    std::promise<T> p;
    auto r = p.get_future();
    master_->post([&] { p.set_value(f()); });
    return r.get();
  }
  NodeState state() {
    return on_master<NodeState>([this] { return machine_->state(); });
  }
  co::NodeStateMachine::Counters counters() {
    return on_master<co::NodeStateMachine::Counters>([this] { return machine_->counters(); });
  }
  lb::Result<void> operator_command(co::NmtCommand c) {
    return on_master<lb::Result<void>>([this, c] { return machine_->operator_command(c); });
  }

  // Waits (generously) until `done()`.
  template <class Done>
  static bool eventually(Done done, std::chrono::seconds within = 15s) {
    const auto deadline = std::chrono::steady_clock::now() + within;
    while (!done()) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(10ms);
    }
    return true;
  }
  // Waits for the machine to be in `s`.
  ::testing::AssertionResult reaches(NodeState s) {
    if (eventually([&] { return state() == s; })) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "never " << co::to_string(s) << "; it is " << co::to_string(state());
  }
  // Waits for the n-th NMT command `cs` to node 9 on the bus.
  ::testing::AssertionResult nmt_seen(std::uint8_t cs, std::size_t n = 1) {
    if (eventually([&] { return nmt_count(cs) >= n; })) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "NMT " << int(cs) << " #" << n << " never on the bus";
  }
  // Power cycles, one after the other (each boot-up believed at the heartbeat that follows it),
  // until the machine backs the device off as a boot-up storm (3 in the fixture's window).
  ::testing::AssertionResult storm() {
    for (int i = 0; i < 3 && state() != NodeState::boot_failed; ++i) {
      const auto boots = counters().boots;
      device_->power_cycle();
      if (!eventually([&] { return counters().boots != boots || state() == NodeState::boot_failed; })) {
        return ::testing::AssertionFailure() << "power cycle " << i + 1 << " was not acted on";
      }
    }
    return reaches(NodeState::boot_failed);
  }
  std::size_t nmt_count(std::uint8_t cs) {
    const auto f = spy_->frames(0x000);
    return std::count_if(f.begin(), f.end(), [cs](const lb::can::CanFrame& x) {
      return x.len == 2 && x.data[0] == cs && x.data[1] == kNode;
    });
  }
  // The frames' positions on the bus: the last NMT `cs`, and whether an SDO request to the node
  // came between `after` and it.
  static std::ptrdiff_t last_nmt(const std::vector<lb::can::CanFrame>& frames, std::uint8_t cs) {
    for (auto i = static_cast<std::ptrdiff_t>(frames.size()) - 1; i >= 0; --i) {
      const auto& f = frames[static_cast<std::size_t>(i)];
      if (f.id == 0 && f.len == 2 && f.data[0] == cs && f.data[1] == kNode) return i;
    }
    return -1;
  }
  static bool sdo_between(const std::vector<lb::can::CanFrame>& frames, std::ptrdiff_t from, std::ptrdiff_t to) {
    for (auto i = from + 1; i < to; ++i) {
      if (frames[static_cast<std::size_t>(i)].id == 0x600u + kNode) return true;
    }
    return false;
  }

  std::string uri_;
  std::unique_ptr<lb::test::BusSpy> spy_;
  std::unique_ptr<ScriptedDevice> device_;
  std::unique_ptr<co::BusLoop> master_;
  std::unique_ptr<co::SdoClient> sdo_;
  std::unique_ptr<co::RemoteNode> node_;
  std::unique_ptr<co::NodeStateMachine> machine_;
  Recorder recorder_;
};

}  // namespace

// unknown → booting → operational: SDO (the boot) before NMT start, and operational only once the
// device's heartbeat says so.
TEST_F(NodeStateMachineTest, AFreshDeviceIsBootedThenOperational) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  const auto frames = spy_->frames();
  const auto start = last_nmt(frames, kStart);
  ASSERT_GE(start, 0);
  EXPECT_TRUE(sdo_between(frames, -1, start)) << "NMT start before any SDO";
  EXPECT_EQ(recorder_.states(), (std::vector<NodeState>{NodeState::booting, NodeState::operational}));
  EXPECT_EQ(device_->state(), kOperational);
}

// A device that answers SDO but sends no heartbeat stays unknown (its probe boots fail with K and
// are retried), and is booted when it is heard.
TEST_F(NodeStateMachineTest, ASilentDeviceStaysUnknownUntilHeard) {
  start_master(kPreOperational, 0x1234, true);
  ASSERT_TRUE(eventually([&] { return counters().boot_failures >= 2; })) << "the probe was not retried";
  EXPECT_GE(counters().boot_failures_by_letter['K' - 'A'], 2u) << "a boot without a heartbeat fails with K";
  EXPECT_EQ(state(), NodeState::unknown);
  EXPECT_EQ(nmt_count(kStart), 0u);
  device_->silence(false);
  ASSERT_TRUE(reaches(NodeState::operational));
  const auto s = recorder_.states();
  EXPECT_EQ(s, (std::vector<NodeState>{NodeState::booting, NodeState::operational}))
      << "a silent device is unknown, not a failed boot";
}

// boot failed (CiA 302-2 D: vendor-ID), retried after the retry interval, never started.
TEST_F(NodeStateMachineTest, AWrongDeviceFailsItsBootAndIsRetriedNeverStarted) {
  start_master(kPreOperational, 0x9999);
  ASSERT_TRUE(reaches(NodeState::boot_failed));
  ASSERT_TRUE(eventually([&] { return counters().boot_failures >= 3; })) << "not retried";
  EXPECT_EQ(nmt_count(kStart), 0u);
  const auto boots = recorder_.boots();
  ASSERT_FALSE(boots.empty());
  ASSERT_TRUE(boots.back().error);
  EXPECT_EQ(boots.back().error->code, 'D');
  EXPECT_EQ(state(), NodeState::boot_failed);
  // Counted by letter for diagnostics and /metrics (index: letter - 'A'): every failure a D.
  const auto c = counters();
  EXPECT_EQ(c.boot_failures_by_letter['D' - 'A'], c.boot_failures);
  EXPECT_EQ(c.boot_failures_by_letter['K' - 'A'], 0u);
  auto r = operator_command(co::NmtCommand::start);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("has not passed its boot"), std::string::npos) << r.error().message;
  EXPECT_EQ(nmt_count(kStart), 0u) << "a refused start went on the bus";
}

// An operator's start that comes while a retry of a failed boot runs is refused with the reason
// the device is not started: the failure of its last boot (CiA 302-2 error D), not only the retry's
// step under way, which says nothing to whoever asks why.
TEST_F(NodeStateMachineTest, AStartDuringABootRetryIsRefusedWithTheLastBootsFailure) {
  start_master(kPreOperational, 0x9999);
  ASSERT_TRUE(reaches(NodeState::boot_failed));
  struct Asked {
    NodeState state;
    bool refused;
    std::string message;
  };
  // Shared with the hook: the loop may still be calling a copy of it when the test goes on.
  struct Probe {
    std::promise<Asked> asked;
    std::once_flag once;
  };
  auto probe = std::make_shared<Probe>();
  // The retry enters booting and then sends its first SDO request: the start is posted from that
  // transition, so it runs on the loop while the retry waits for its first answer.
  recorder_.on_every_state([this, probe](NodeState s) {
    if (s != NodeState::booting) return;
    std::call_once(probe->once, [this, probe] {
      master_->post([this, probe] {
        auto r = machine_->operator_command(co::NmtCommand::start);
        probe->asked.set_value({machine_->state(), !r, r ? std::string() : r.error().message});
      });
    });
  });
  auto answer = probe->asked.get_future();
  ASSERT_EQ(answer.wait_for(15s), std::future_status::ready) << "no retry was seen";
  recorder_.on_every_state({});
  const auto a = answer.get();
  EXPECT_EQ(a.state, NodeState::booting) << "the start did not come during the retry: the test proves nothing";
  ASSERT_TRUE(a.refused) << "a device whose boot failed was started";
  EXPECT_NE(a.message.find("has not passed its boot"), std::string::npos) << a.message;
  EXPECT_NE(a.message.find("its last boot failed: CiA 302-2 error D"), std::string::npos) << a.message;
  EXPECT_EQ(nmt_count(kStart), 0u) << "a refused start went on the bus";
}

// A running device whose boot fails on something asking again will not change (its identity) is
// left running and reported: running unmanaged, no NMT command at all.
TEST_F(NodeStateMachineTest, ARunningWrongDeviceIsLeftRunningUnmanaged) {
  start_master(kOperational, 0x9999);
  ASSERT_TRUE(reaches(NodeState::running_unmanaged));
  EXPECT_EQ(spy_->frames(0x000).size(), 0u) << "an NMT command reached a device the bridge does not manage";
  EXPECT_EQ(device_->state(), kOperational);
  // A heartbeat loss ends it: lost, then probed again when it is back.
  device_->silence(true);
  ASSERT_TRUE(reaches(NodeState::lost));
  device_->silence(false);
  ASSERT_TRUE(reaches(NodeState::running_unmanaged));
}

// A device held stopped (an operator's stop kept from before a restart) that runs, and whose boot
// fails (not the device the line configures here: vendor-ID 1234h where 9999h is expected), is
// stopped all the same: a failed boot never leaves a held device running. It is never started.
TEST_F(NodeStateMachineTest, AHeldDeviceWhoseBootFailsIsStoppedAllTheSame) {
  start_master(kOperational, 0x9999, false, co::NmtCommand::stop);
  ASSERT_TRUE(nmt_seen(kStop, 1)) << "the held device runs on after its failed boot";
  EXPECT_TRUE(eventually([&] { return device_->state() == kStopped; }));
  EXPECT_EQ(nmt_count(kStart), 0u) << "a held device whose boot failed was started";
}

// operational → lost → booting → operational: a device back after a loss is booted again (SDO
// before the second NMT start), never started bare.
TEST_F(NodeStateMachineTest, ADeviceBackAfterALossIsBootedAgain) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  device_->silence(true);
  ASSERT_TRUE(reaches(NodeState::lost));
  device_->report(kPreOperational);  // it lost power meanwhile, and its boot-up was not heard
  device_->silence(false);
  ASSERT_TRUE(nmt_seen(kStart, 2));
  ASSERT_TRUE(reaches(NodeState::operational));
  const auto frames = spy_->frames();
  const auto first = std::find_if(frames.begin(), frames.end(),
                                  [](const auto& f) { return f.id == 0 && f.data[0] == kStart; }) -
                     frames.begin();
  EXPECT_TRUE(sdo_between(frames, first, last_nmt(frames, kStart))) << "started again without a boot";
  const auto s = recorder_.states();
  const std::vector<NodeState> expected{NodeState::booting, NodeState::operational, NodeState::lost, NodeState::booting,
                                        NodeState::operational};
  EXPECT_EQ(s, expected);
}

// A state nobody commanded (pre-operational while told operational): booted again.
TEST_F(NodeStateMachineTest, AStateNotCommandedBootsItAgain) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  device_->report(kPreOperational);
  ASSERT_TRUE(nmt_seen(kStart, 2));
  ASSERT_TRUE(reaches(NodeState::operational));
  EXPECT_EQ(counters().state_unknown, 1u);
  const auto s = recorder_.states();
  ASSERT_GE(s.size(), 4u);
  EXPECT_EQ(s[2], NodeState::booting);
}

// A reset always leads to a boot: the device's boot-up is lost; after the bound the master boots
// it (SDO, then NMT start), and it is never operational in between.
TEST_F(NodeStateMachineTest, AResetWhoseBootUpIsLostEndsInABootNotInLimbo) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  device_->drop_next_boot_up();
  ASSERT_TRUE(operator_command(co::NmtCommand::reset_node));
  EXPECT_EQ(state(), NodeState::resetting);
  ASSERT_TRUE(nmt_seen(kStart, 2));
  ASSERT_TRUE(reaches(NodeState::operational));
  const auto frames = spy_->frames();
  EXPECT_TRUE(sdo_between(frames, last_nmt(frames, kResetNode), last_nmt(frames, kStart)));
  const std::vector<NodeState> expected{NodeState::booting, NodeState::operational, NodeState::resetting,
                                        NodeState::booting, NodeState::operational};
  EXPECT_EQ(recorder_.states(), expected);
}

// A boot-up storm: backed off (boot failed, counted once), not booted at every boot-up; an
// operator's reset ends the back-off and boots it.
TEST_F(NodeStateMachineTest, ABootUpStormIsBackedOffAndAnOperatorResetEndsIt) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  ASSERT_TRUE(storm());
  EXPECT_EQ(counters().storms, 1u);
  const auto starts = nmt_count(kStart);
  EXPECT_EQ(device_->state(), kPreOperational);
  ASSERT_TRUE(operator_command(co::NmtCommand::reset_node));
  ASSERT_TRUE(nmt_seen(kStart, starts + 1));
  ASSERT_TRUE(reaches(NodeState::operational));
}

// An operator's stop sticks: across a heartbeat loss and a power cycle the device is configured
// again and put back in stopped (NMT stop), never started, until an operator starts it.
TEST_F(NodeStateMachineTest, AnOperatorStopSticksUntilAnOperatorStarts) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  ASSERT_TRUE(operator_command(co::NmtCommand::stop));
  EXPECT_EQ(state(), NodeState::stopped_by_operator);
  device_->silence(true);
  ASSERT_TRUE(reaches(NodeState::lost));
  device_->power_cycle();  // while silent: its boot-up is heard, heartbeats resume below
  device_->silence(false);
  ASSERT_TRUE(nmt_seen(kStop, 2));
  ASSERT_TRUE(reaches(NodeState::stopped_by_operator));
  EXPECT_EQ(nmt_count(kStart), 1u) << "the stopped device was started without an operator";
  EXPECT_EQ(device_->state(), kStopped);
  ASSERT_TRUE(operator_command(co::NmtCommand::start));
  ASSERT_TRUE(reaches(NodeState::operational));
  EXPECT_EQ(device_->state(), kOperational);
}

// A spoofed boot-up next to a running device (its heartbeat goes on saying operational) is not
// believed: no transition, no boot.
TEST_F(NodeStateMachineTest, ASpoofedBootUpChangesNothing) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  const auto boots = counters().boots;
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x700 + kNode, {kBootUp})));
  ASSERT_TRUE(eventually([&] {
    return on_master<std::uint32_t>([this] { return node_->stats().boot_ups_not_believed; }) != 0;
  })) << "the boot-up was never judged";
  EXPECT_EQ(state(), NodeState::operational);
  EXPECT_EQ(counters().boots, boots);
  EXPECT_EQ(recorder_.states(), (std::vector<NodeState>{NodeState::booting, NodeState::operational}));
}

// The storm's back-off is a timeout too: when it ends, the device is booted again by itself
// (boot failed → booting → operational), SDO before its NMT start.
TEST_F(NodeStateMachineTest, ABootUpStormsBackOffEndsInABoot) {
  start_master(kPreOperational);
  ASSERT_TRUE(reaches(NodeState::operational));
  ASSERT_TRUE(storm());
  const auto starts = nmt_count(kStart);
  ASSERT_TRUE(nmt_seen(kStart, starts + 1));  // after the back-off (retry: 300 ms), nobody asking
  ASSERT_TRUE(reaches(NodeState::operational));
  const auto s = recorder_.states();
  const auto failed = std::find(s.begin(), s.end(), NodeState::boot_failed);
  ASSERT_NE(failed, s.end());
  ASSERT_LT(failed + 1, s.end());
  EXPECT_EQ(*(failed + 1), NodeState::booting);
  EXPECT_EQ(s.back(), NodeState::operational);
  const auto frames = spy_->frames();
  const auto last = last_nmt(frames, kStart);
  std::ptrdiff_t previous = -1;
  for (std::ptrdiff_t i = last - 1; i >= 0; --i) {
    const auto& f = frames[static_cast<std::size_t>(i)];
    if (f.id == 0x700u + kNode && f.len == 1 && f.data[0] == kBootUp) {
      previous = i;
      break;
    }
  }
  EXPECT_TRUE(sdo_between(frames, previous, last)) << "started after the storm without a boot";
}

// A standby takes the bus over (docs/redundancy.md): the device it hears operational is adopted as
// it runs, and what it says about itself is read by uploads only after the first SYNC and told to
// the drivers as a report (adopted, started, the identity its dictionary holds: vendor-ID 1234h,
// product 1, revision 2, serial 3; the optional objects it lacks as remarks). No NMT command, no
// SDO download, never out of operational, and no boot.
TEST_F(NodeStateMachineTest, AnAdoptedDeviceIsReadByUploadsNeverWritten) {
  start_master(kOperational, 0x1234, false, std::nullopt, true);
  ASSERT_TRUE(take_over(co::NmtCommand::start));
  EXPECT_EQ(state(), NodeState::operational);
  const auto report = first_report();
  ASSERT_TRUE(report) << "no report of the adopted device; " << detail();
  EXPECT_TRUE(report->adopted);
  EXPECT_TRUE(report->started);
  EXPECT_FALSE(report->held_by_operator);
  EXPECT_FALSE(report->error);
  EXPECT_TRUE(report->warnings.empty());
  EXPECT_EQ(report->identity.device_type, 0x1A4u);
  EXPECT_EQ(report->identity.vendor_id, 0x1234u);
  EXPECT_EQ(report->identity.product_code, 1u);
  EXPECT_EQ(report->identity.revision_number, 2u);
  EXPECT_EQ(report->identity.serial_number, 3u);
  EXPECT_NE(report->identity.remarks.find("device name: not implemented"), std::string::npos)
      << report->identity.remarks;
  EXPECT_NE(report->identity.remarks.find("heartbeat producer time 1017h: not implemented"), std::string::npos)
      << report->identity.remarks;
  EXPECT_FALSE(report->heartbeat_producer_ms);
  EXPECT_NE(detail().find("adopted at a takeover (no NMT, no SDO download); its identity read (SDO uploads only) "
                          "is what the line expects"),
            std::string::npos)
      << detail();
  EXPECT_EQ(state(), NodeState::operational);
  EXPECT_EQ(device_->state(), kOperational);
  EXPECT_EQ(spy_->frames(0x000).size(), 0u) << "an NMT command to an adopted device";
  EXPECT_GE(sdo_uploads_only(5), 5u);  // 1000h, 1018h sub 1..4 at least
  const auto c = counters();
  EXPECT_EQ(c.adopted, 1u);
  EXPECT_EQ(c.boots, 0u);
  EXPECT_EQ(c.adopted_identity_mismatches, 0u);
  EXPECT_EQ(recorder_.states(), (std::vector<NodeState>{NodeState::operational}));
}

// The device the standby adopts is not the one the line expects here (vendor-ID 1234h where 9999h
// is expected): it runs on (a boot would leave it running unmanaged; an adoption keeps it
// operational, as the master before ran it), and the report's warnings and the diagnostics' detail
// say it with the boot's letter; no NMT command, no SDO download.
TEST_F(NodeStateMachineTest, AnAdoptedDeviceOfAnotherIdentityRunsOnAndIsReported) {
  start_master(kOperational, 0x9999, false, std::nullopt, true);
  ASSERT_TRUE(take_over(co::NmtCommand::start));
  const auto report = first_report();
  ASSERT_TRUE(report) << "no report of the adopted device; " << detail();
  EXPECT_TRUE(report->adopted);
  EXPECT_TRUE(report->started);
  EXPECT_FALSE(report->error) << "no boot failed: the mismatch is a warning";
  ASSERT_FALSE(report->warnings.empty());
  const auto& w = report->warnings.front();
  EXPECT_NE(w.find("ITS IDENTITY IS NOT THE LINE'S: node 9: vendor-ID (1018h sub 1) is 0000 1234h, the line expects "
                   "0000 9999h"),
            std::string::npos)
      << w;
  EXPECT_NE(w.find("CiA 302-2 error D"), std::string::npos) << w;
  EXPECT_EQ(report->identity.vendor_id, 0x1234u);
  EXPECT_NE(detail().find("ITS IDENTITY IS NOT THE LINE'S"), std::string::npos) << detail();
  EXPECT_EQ(state(), NodeState::operational);
  EXPECT_EQ(device_->state(), kOperational);
  EXPECT_EQ(spy_->frames(0x000).size(), 0u) << "an NMT command to an adopted device";
  EXPECT_GE(sdo_uploads_only(5), 5u);
  EXPECT_EQ(counters().adopted_identity_mismatches, 1u);
  EXPECT_EQ(counters().boots, 0u);
}

// Adopted held stopped (the master before stopped it): a stopped device answers no SDO (CiA 301),
// so nothing is asked after the SYNC; once an operator starts it, it is read, and the report says
// it runs.
TEST_F(NodeStateMachineTest, AnAdoptedStoppedDeviceIsReadOnceItIsStarted) {
  start_master(kStopped, 0x1234, false, std::nullopt, true);
  ASSERT_TRUE(take_over(co::NmtCommand::stop));
  EXPECT_EQ(state(), NodeState::stopped_by_operator);
  // The SYNC's posted reading has run by now (posted before this question): it waits.
  EXPECT_NE(detail().find("its identity is read once it is heard in another state"), std::string::npos) << detail();
  EXPECT_EQ(spy_->frames(0x600u + kNode).size(), 0u) << "an SDO request to a stopped device";
  EXPECT_TRUE(recorder_.boots().empty());
  ASSERT_TRUE(operator_command(co::NmtCommand::start));
  ASSERT_TRUE(reaches(NodeState::operational));
  const auto report = first_report();
  ASSERT_TRUE(report) << "no report once it was started; " << detail();
  EXPECT_TRUE(report->adopted);
  EXPECT_TRUE(report->started);
  EXPECT_FALSE(report->held_by_operator);
  EXPECT_EQ(report->identity.vendor_id, 0x1234u);
  EXPECT_GE(sdo_uploads_only(5), 5u);
  EXPECT_EQ(nmt_count(kStart), 1u);  // the operator's, nothing else
  EXPECT_EQ(counters().boots, 0u);
}
