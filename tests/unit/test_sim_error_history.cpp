// The simulator's 1003h (pre-defined error field) is an error HISTORY, as CiA 301 defines it, and
// the bridge reads it as one. A simulated saw and a master (bus loop, SDO client, EMCY listener)
// in this process on one virtual bus; errors raised and cleared through the simulator's error
// simulation 2003h (bits 0..15 a code to raise, bit 31 set: the code to clear, 8000 0000h: all).
//
// Every expected value is written here by hand from CiA 301 (cia301-essentials.md; 1003h: sub 0
// the number of errors recorded, sub 1 the newest, older ones shift up; every EMCY recorded, the
// error reset 0000h included, as CANopenNode does; writing 0 to sub 0 clears the history, any
// other value is refused with 0609 0030h; sub 1..n read-only, 0601 0002h) and from the error
// register bits (0 generic, 2 voltage, 3 temperature). The simulator keeps 8 entries (its
// documented size), the bridge reads the newest 16 at most.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/emcy.hpp"
#include "canopen/error_field.hpp"
#include "canopen/sdo_client.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "sim/device_simulator.hpp"

namespace {

using namespace std::chrono_literals;
using Entries = std::vector<std::uint64_t>;

constexpr std::uint8_t kNode = 5;
constexpr std::uint16_t kErrorField = 0x1003, kErrorRegister = 0x1001, kErrorSimulation = 0x2003;
constexpr std::uint32_t kClear = 0x8000'0000;
constexpr std::uint32_t kRange = 0x0609'0030, kReadOnly = 0x0601'0002;
constexpr std::uint16_t kTemperature = 0x4210, kVoltage = 0x3120;

struct Sdo {
  bool ok = false;
  std::uint64_t value = 0;
  std::uint32_t abort = 0;
};

class SimErrorHistory : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string bus = "virtual:eh" + std::to_string(::getpid()) + "-" + info->name();
    bus.resize(std::min<std::size_t>(bus.size(), 90));
    auto config =
        lb::profiles::parse_line_config("line: history\n"
                                        "buses:\n"
                                        "  - {name: b, interface: '" +
                                            bus +
                                            "'}\n"
                                            "devices:\n"
                                            "  - {name: saw, bus: b, node_id: 5, profile: cia420-4, version: '3.1'}\n",
                                        "history.yaml", registry_);
    ASSERT_TRUE(config) << config.error().message;
    config_ = std::move(*config);
    // The master's loop first: the hub lives in it.
    master_ = std::make_unique<lb::canopen::BusLoop>(lb::can::open_bus(bus).value());
    sdo_ = std::make_unique<lb::canopen::SdoClient>(*master_, 500ms);
    // The bridge's side of the EMCYs (080h + node-ID), on the master's loop thread.
    master_->on_frame(0x80 + kNode, [this](const lb::can::CanFrame& f) {
      if (auto e = lb::canopen::parse_emergency(f)) {
        std::lock_guard lock(m_);
        active_.apply(*e);
        ++emcys_;
      }
    });
    device_loop_ = std::make_unique<lb::canopen::BusLoop>(lb::can::open_bus(bus).value());
    device_ = lb::sim::make_simulator(*device_loop_, config_.devices.at(0));
    device_->start();
    master_->start();
    device_loop_->start();
    // Its boot-up: the device starts without active errors.
    std::lock_guard lock(m_);
    active_.reset_by_boot_up();
  }
  void TearDown() override {
    if (device_loop_) device_loop_->stop();
    if (master_) master_->stop();
  }

  Sdo read(std::uint16_t index, std::uint8_t sub) {
    auto r = sdo_->upload_async(kNode, index, sub).get();
    if (!r) return {false, 0, r.error().abort_code};
    Sdo out{true, 0, 0};
    for (std::size_t i = 0; i < r->size() && i < 8; ++i) out.value |= std::uint64_t{(*r)[i]} << (8 * i);
    return out;
  }
  std::uint32_t write(std::uint16_t index, std::uint8_t sub, std::uint64_t value, std::size_t size) {
    std::vector<std::uint8_t> bytes(size);
    for (std::size_t i = 0; i < size; ++i) bytes[i] = static_cast<std::uint8_t>(value >> (8 * i));
    auto r = sdo_->download_async(kNode, index, sub, std::move(bytes)).get();
    return r ? 0 : r.error().abort_code;
  }
  // 2003h, then wait for the `emcys` EMCYs it makes the device send.
  void simulate(std::uint32_t value, int emcys) {
    const int before = emcy_count();
    ASSERT_EQ(write(kErrorSimulation, 0, value, 4), 0u);
    const auto end = std::chrono::steady_clock::now() + 3s;
    while (emcy_count() < before + emcys && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(5ms);
    ASSERT_EQ(emcy_count(), before + emcys) << "2003h = " << std::hex << value;
  }
  int emcy_count() {
    std::lock_guard lock(m_);
    return emcys_;
  }
  // 1003h as a master reads it: sub 0, then sub 1..n.
  Entries history() {
    const auto count = read(kErrorField, 0);
    EXPECT_TRUE(count.ok);
    Entries out;
    for (std::uint64_t sub = 1; sub <= count.value && sub <= 254; ++sub) {
      const auto r = read(kErrorField, static_cast<std::uint8_t>(sub));
      EXPECT_TRUE(r.ok) << "sub " << sub;
      out.push_back(r.value);
    }
    return out;
  }
  lb::canopen::ErrorFieldReading bridge_reading() {
    std::promise<lb::canopen::ErrorFieldReading> done;
    master_->post([this, &done] {
      lb::canopen::read_error_field(*sdo_, kNode, {},
                                    [&done](lb::canopen::ErrorFieldReading r) { done.set_value(std::move(r)); });
    });
    return done.get_future().get();
  }

  const lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  lb::profiles::LineConfig config_;
  std::unique_ptr<lb::canopen::BusLoop> master_;
  std::unique_ptr<lb::canopen::SdoClient> sdo_;
  std::unique_ptr<lb::canopen::BusLoop> device_loop_;
  std::unique_ptr<lb::sim::DeviceSimulator> device_;
  std::mutex m_;
  lb::canopen::ActiveErrors active_;  // guarded by m_
  int emcys_ = 0;                     // guarded by m_
};

}  // namespace

TEST_F(SimErrorHistory, EveryEmcyIsRecordedNewestFirstErrorResetsIncluded) {
  EXPECT_EQ(history(), Entries{}) << "nothing recorded after power-on";
  simulate(kTemperature, 1);           // EMCY 4210h
  simulate(kVoltage, 1);               // EMCY 3120h
  simulate(kClear | kTemperature, 1);  // EMCY 0000h, register 05h: the voltage error remains
  EXPECT_EQ(read(kErrorRegister, 0).value, 0x05u);
  EXPECT_EQ(history(), (Entries{0x0000, 0x3120, 0x4210})) << "sub 0 = 3; sub 1 the newest: the error reset";
  simulate(kClear, 1);  // EMCY 0000h, register 00h
  EXPECT_EQ(read(kErrorRegister, 0).value, 0x00u);
  EXPECT_EQ(history(), (Entries{0x0000, 0x0000, 0x3120, 0x4210})) << "no error active, and the history keeps them all";
}

TEST_F(SimErrorHistory, BoundedTheOldestDropped) {
  for (std::uint32_t code = 0x5001; code <= 0x5005; ++code) simulate(code, 1);
  simulate(kClear, 1);  // 0000h
  simulate(0x5006, 1);
  simulate(0x5007, 1);
  EXPECT_EQ(history(), (Entries{0x5007, 0x5006, 0x0000, 0x5005, 0x5004, 0x5003, 0x5002, 0x5001}));
  simulate(0x5008, 1);
  EXPECT_EQ(history(), (Entries{0x5008, 0x5007, 0x5006, 0x0000, 0x5005, 0x5004, 0x5003, 0x5002}))
      << "8 entries: the oldest, 5001h, falls off";
}

TEST_F(SimErrorHistory, WritingZeroToSub0ClearsTheHistoryNotTheErrors) {
  simulate(kTemperature, 1);
  simulate(kVoltage, 1);
  ASSERT_EQ(history(), (Entries{0x3120, 0x4210}));
  const int emcys = emcy_count();
  EXPECT_EQ(write(kErrorField, 0, 0, 1), 0u);
  EXPECT_EQ(read(kErrorField, 0).value, 0u);
  EXPECT_EQ(read(kErrorRegister, 0).value, 0x0Du) << "both errors still active: generic, voltage, temperature";
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(emcy_count(), emcys) << "deleting the history is no error reset: no EMCY";
  simulate(kClear | kVoltage, 1);  // 0000h, register 09h
  EXPECT_EQ(history(), (Entries{0x0000})) << "recording starts again at sub 1";
}

TEST_F(SimErrorHistory, OtherWritesAreRefusedAndChangeNothing) {
  simulate(kTemperature, 1);
  simulate(kClear | kTemperature, 1);
  ASSERT_EQ(history(), (Entries{0x0000, 0x4210}));
  EXPECT_EQ(write(kErrorField, 0, 1, 1), kRange) << "only 0 may be written to sub 0";
  EXPECT_EQ(write(kErrorField, 0, 2, 1), kRange);
  EXPECT_EQ(write(kErrorField, 0, 0xFF, 1), kRange);
  EXPECT_EQ(write(kErrorField, 1, 0, 4), kReadOnly) << "sub 1..n are read-only";
  EXPECT_EQ(write(kErrorField, 2, 0x1234, 4), kReadOnly);
  EXPECT_EQ(history(), (Entries{0x0000, 0x4210}));
}

// The bridge's side: read_error_field returns 1003h as history (newest first, 0000h included), and
// the active errors come from the EMCYs and 1001h only.
TEST_F(SimErrorHistory, TheBridgeReadsItAsHistoryNotAsTheActiveErrors) {
  simulate(kTemperature, 1);
  simulate(kVoltage, 1);
  simulate(kClear | kTemperature, 1);  // 0000h with register 05h
  auto r = bridge_reading();
  ASSERT_FALSE(r.error) << r.error->message;
  EXPECT_EQ(r.error_register, 0x05);
  ASSERT_TRUE(r.history.read) << r.history.remark;
  EXPECT_EQ(r.history.count, 3);
  EXPECT_EQ(r.history.entries, (std::vector<std::uint32_t>{0x0000, 0x3120, 0x4210}));
  {
    std::lock_guard lock(m_);
    lb::canopen::apply(active_, r);
    // Some error remains and neither the EMCY nor 1001h says which; the history cannot either.
    EXPECT_FALSE(active_.known());
    EXPECT_EQ(active_.codes(), (std::vector<std::uint16_t>{0x4210, 0x3120})) << "nothing dropped on a guess";
    EXPECT_EQ(active_.error_register(), 0x05);
  }
  simulate(kClear | kVoltage, 1);  // 0000h with register 00h
  r = bridge_reading();
  EXPECT_EQ(r.error_register, 0x00);
  EXPECT_EQ(r.history.entries, (std::vector<std::uint32_t>{0x0000, 0x0000, 0x3120, 0x4210}));
  std::lock_guard lock(m_);
  lb::canopen::apply(active_, r);
  EXPECT_TRUE(active_.known());
  EXPECT_TRUE(active_.codes().empty()) << "register 0: nothing active, whatever the history holds";
}
