// BootSequence on the master side against a real SDO server on a virtual bus: the boot path of a
// device whose profile has no `pdos:` (a device the line only supervises and configures). Its
// boot must read no PDO parameters and go on to the configuration and the start, not look at the
// last reply of an empty batch.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <future>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>

#include "canopen/boot_sequence.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sdo_server.hpp"
#include "support/bus_spy.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;

namespace {

constexpr std::uint8_t kNode = 9;
constexpr std::uint16_t kProfile = 0x1A4;  // the device type's profile number (1000h bits 0..15)

co::ObjectDictionary device_dictionary() {
  co::ObjectDictionary od;
  const auto add = [&](std::uint16_t index, std::uint8_t sub, co::DataType type, std::vector<std::uint8_t> value) {
    if (auto r = od.add(index, sub, type, co::ObjectAccess::ro, std::move(value)); !r) {
      throw std::runtime_error(r.error().message);
    }
  };
  add(0x1000, 0, co::DataType::unsigned32, {0xA4, 0x01, 0x00, 0x00});
  add(0x1018, 1, co::DataType::unsigned32, {0x34, 0x12, 0x00, 0x00});  // vendor-ID 1234h
  add(0x1018, 2, co::DataType::unsigned32, {0x01, 0x00, 0x00, 0x00});
  add(0x1018, 3, co::DataType::unsigned32, {0x02, 0x00, 0x00, 0x00});
  add(0x1018, 4, co::DataType::unsigned32, {0x03, 0x00, 0x00, 0x00});
  return od;  // no PDO objects at all (1400h..1BFFh), as the profile has none
}

}  // namespace

TEST(BootSequence, AProfileWithoutPdosBootsAndStartsTheDevice) {
  const std::string uri = "virtual:boot-" + std::to_string(::getpid()) + "-" +
                          ::testing::UnitTest::GetInstance()->current_test_info()->name();
  lb::test::BusSpy spy(uri);
  co::BusLoop master(lb::can::open_bus(uri).value());
  co::BusLoop device(lb::can::open_bus(uri).value());
  co::SdoServer server(device, kNode, device_dictionary());
  co::SdoClient sdo(master);
  co::RemoteNode node(master, kNode, 5000ms, true);
  co::BootSequence::Settings settings;
  settings.identity.profile_number = kProfile;
  settings.identity.vendor_id = 0x1234;
  co::BootSequence boot(master, node, sdo, settings);  // settings.pdos: empty
  // What the node state machine does for the boot: every heartbeat is told to it.
  struct HeartbeatsToBoot final : co::NodeDriver {
    explicit HeartbeatsToBoot(co::BootSequence& b) : boot(b) {}
    void on_heartbeat(co::NmtState s) noexcept override { boot.heard(s); }
    co::BootSequence& boot;
  } to_boot(boot);
  node.attach(to_boot);
  master.start();
  device.start();

  // The device is alive (pre-operational, a heartbeat every 50 ms): the boot starts it after the
  // first heartbeat that follows its configuration.
  std::jthread heartbeats([&spy](std::stop_token stop) {
    while (!stop.stop_requested()) {
      (void)spy.send(lb::can::make_frame(0x700 + kNode, {0x7F}));
      std::this_thread::sleep_for(50ms);
    }
  });
  const auto poll_online = [&] {
    std::promise<bool> p;
    auto f = p.get_future();
    master.post([&] { p.set_value(node.online()); });
    return f.get();
  };
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!poll_online()) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "the heartbeat never reached the master";
    std::this_thread::sleep_for(5ms);
  }

  std::promise<co::BootReport> done;
  auto report_future = done.get_future();
  master.post([&] { boot.run([&](const co::BootReport& r) { done.set_value(r); }); });
  ASSERT_EQ(report_future.wait_for(10s), std::future_status::ready) << "the boot never ended";
  const co::BootReport report = report_future.get();
  heartbeats.request_stop();
  heartbeats.join();
  master.stop();
  device.stop();

  ASSERT_FALSE(report.error) << report.error->message;
  EXPECT_TRUE(report.started);
  EXPECT_EQ(report.identity.vendor_id, 0x1234u);
  EXPECT_TRUE(report.pdos.empty());
  // No PDO parameter was asked for, and the device was told to start (NMT start, node 9).
  bool pdo_read = false, started = false;
  for (const auto& f : spy.frames()) {
    if (f.id == 0x600u + kNode && f.len == 8) {
      const unsigned index = f.data[1] | f.data[2] << 8;
      pdo_read = pdo_read || (index >= 0x1400 && index <= 0x1BFF);
    }
    started = started || (f.id == 0 && f.len == 2 && f.data[0] == 0x01 && f.data[1] == kNode);
  }
  EXPECT_FALSE(pdo_read);
  EXPECT_TRUE(started);
}
