// IdentityReader (canopen/identity_reader): what a device says about itself, read by SDO uploads
// only, and judged against the line's expected identity. Against a simulated saw (linebridge-sim's
// device, on its own loop) whose 1000h, 1018h and 1017h come from its `simulation:` section, and
// against a bare CiA 301 SDO server that lacks every optional object. A master loop and its
// SdoClient in this process on the test's own virtual bus (LoopOnOwnBus), every frame recorded.
//
// Expected values are this file's: the simulation section below (written by hand), CiA 301
// (1000h bits 0..15 the profile number, 420 = 01A4h; 1018h sub 1..4 vendor-ID, product code,
// revision, serial number; 1017h in ms; what an SDO request asks: support/sdo_frames.hpp) and
// CiA 302-2's boot error letters (C device type, D vendor-ID, M product code, B no answer).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "can/bus.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/identity_reader.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "sim/device_simulator.hpp"
#include "support/bus_spy.hpp"
#include "support/sdo_frames.hpp"
#include "support/unit_loop_fixture.hpp"

namespace {

using namespace std::chrono_literals;
namespace co = lb::canopen;

constexpr std::uint8_t kSaw = 5;
constexpr std::uint8_t kBare = 12;    // the bare SDO server
constexpr std::uint8_t kNobody = 20;  // no device at this node-ID
// The simulated saw's hardware, as its simulation section below gives it.
constexpr std::uint32_t kDeviceType = 0x000401A4;  // profile 420 (01A4h)
constexpr std::uint32_t kVendor = 0x00ABCDEF;
constexpr std::uint32_t kProduct = 0x04200004;
constexpr std::uint32_t kRevision = 0x00030001;
constexpr std::uint32_t kSerial = 0x00C0FFEE;
constexpr std::uint16_t kHeartbeatMs = 70;
constexpr std::uint16_t kProfile420 = 0x01A4;

// CiA 301 objects a device must have (1000h, 1018h sub 1) and nothing optional: no 1018h sub 2..4,
// no 1008h..100Ah, no 1017h.
co::ObjectDictionary bare_dictionary() {
  co::ObjectDictionary od;
  const auto add = [&](std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> value) {
    if (auto r = od.add(index, sub, co::DataType::unsigned32, co::ObjectAccess::ro, std::move(value)); !r)
      throw std::runtime_error(r.error().message);
  };
  add(0x1000, 0, {0xA4, 0x01, 0x00, 0x00});
  add(0x1018, 1, {0x34, 0x12, 0x00, 0x00});  // vendor-ID 1234h
  return od;
}

class IdentityReaderTest : public lb::test::LoopOnOwnBus {
 protected:
  IdentityReaderTest() : LoopOnOwnBus("idr") {}
  void SetUp() override {
    LoopOnOwnBus::SetUp();
    const auto& bus = uri_;
    auto config = lb::profiles::parse_line_config(
        "line: identity\n"
        "buses:\n"
        "  - {name: b, interface: '" +
            bus +
            "'}\n"
            "devices:\n"
            "  - name: saw\n"
            "    bus: b\n"
            "    node_id: 5\n"
            "    profile: cia420-4\n"
            "    version: '3.1'\n"
            "    simulation:\n"
            "      heartbeat_period_ms: 70\n"
            "      identity: {device_type: 0x000401A4, vendor_id: 0x00ABCDEF, product_code: 0x04200004, revision: "
            "0x00030001, serial_number: 0x00C0FFEE}\n",
        "identity.yaml", registry_);
    ASSERT_TRUE(config) << config.error().message;
    config_ = std::move(*config);
    sdo_ = std::make_unique<co::SdoClient>(*loop_, 300ms);
    device_loop_ = std::make_unique<co::BusLoop>(lb::can::open_bus(bus).value());
    device_ = lb::sim::make_simulator(*device_loop_, config_.devices.at(0));
    bare_ = std::make_unique<co::SdoServer>(*device_loop_, kBare, bare_dictionary());
    device_->start();
    loop_->start();
    device_loop_->start();
  }
  void TearDown() override {
    if (device_loop_) device_loop_->stop();
    LoopOnOwnBus::TearDown();
    sdo_.reset();
  }

  co::IdentityReader reader(std::uint8_t node, co::ExpectedIdentity expected) const {
    return co::IdentityReader(*sdo_, node, std::move(expected));
  }
  // read_all on the master's loop; the reading, or a failure when it never ended.
  co::IdentityReader::Reading read_all(const co::IdentityReader& r) {
    auto done = std::make_shared<std::promise<co::IdentityReader::Reading>>();
    auto f = done->get_future();
    loop_->post([&r, done] {
      r.read_all([] { return false; }, [done](co::IdentityReader::Reading x) { done->set_value(std::move(x)); });
    });
    if (f.wait_for(10s) != std::future_status::ready) throw std::runtime_error("the reading never ended");
    return f.get();
  }
  co::IdentityReader::Check check(const co::IdentityReader& r) {
    auto done = std::make_shared<std::promise<co::IdentityReader::Check>>();
    auto f = done->get_future();
    loop_->post([&r, done] {
      r.check([] { return false; }, [done](co::IdentityReader::Check x) { done->set_value(std::move(x)); });
    });
    if (f.wait_for(10s) != std::future_status::ready) throw std::runtime_error("the check never ended");
    return f.get();
  }
  // Every SDO request to `node` on the bus was an upload (CiA 301 ccs 2: initiate, 3: segment) or
  // an abort (ccs 4); how many were seen. The reading is over: once the spy has seen an answer to
  // every request (and at least `min` of them), it has seen all of them.
  std::size_t uploads_only(std::uint8_t node, std::size_t min) {
    const auto count = [node](const std::vector<lb::can::CanFrame>& all, std::uint32_t base) {
      return static_cast<std::size_t>(
          std::count_if(all.begin(), all.end(), [&](const auto& f) { return f.id == base + node; }));
    };
    EXPECT_TRUE(spy_->wait_until([&](const auto& all) {
      const auto requests = count(all, 0x600);
      return requests >= min && count(all, 0x580) == requests;
    })) << "the spy never saw the reading's frames to node "
        << int(node);
    std::size_t requests = 0;
    for (const auto& f : spy_->frames(0x600u + node)) {
      ++requests;
      EXPECT_GE(f.len, 1);
      EXPECT_FALSE(lb::test::sdo_download(f))
          << "an SDO download to node " << int(node) << ": command byte " << std::hex << int(f.data[0]);
    }
    return requests;
  }

  const lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  lb::profiles::LineConfig config_;
  std::unique_ptr<co::SdoClient> sdo_;
  std::unique_ptr<co::BusLoop> device_loop_;
  std::unique_ptr<lb::sim::DeviceSimulator> device_;
  std::unique_ptr<co::SdoServer> bare_;
};

}  // namespace

// The device the line expects: every value as its hardware has it, names read, 1017h as it sends
// its heartbeat; nothing but uploads on the bus.
TEST_F(IdentityReaderTest, ReadsWhatTheDeviceSaysByUploadsOnly) {
  const auto r = reader(kSaw, {kProfile420, kDeviceType, kVendor, kProduct, kRevision, kSerial});
  const auto reading = read_all(r);
  const auto& c = reading.check;
  EXPECT_FALSE(c.error) << c.error->message;
  EXPECT_TRUE(c.answered);
  EXPECT_EQ(c.identity.device_type, kDeviceType);
  EXPECT_EQ(c.identity.vendor_id, kVendor);
  EXPECT_EQ(c.identity.product_code, kProduct);
  EXPECT_EQ(c.identity.revision_number, kRevision);
  EXPECT_EQ(c.identity.serial_number, kSerial);
  // 1008h..100Ah are the device's own texts (CiA 301 VISIBLE_STRING): present, so no remark.
  EXPECT_FALSE(c.identity.device_name.empty());
  EXPECT_FALSE(c.identity.hardware_version.empty());
  EXPECT_FALSE(c.identity.software_version.empty());
  EXPECT_EQ(c.identity.remarks, "");
  EXPECT_GT(c.identity.read_at_ns, 0);
  ASSERT_TRUE(reading.heartbeat_producer_ms);
  EXPECT_EQ(*reading.heartbeat_producer_ms, kHeartbeatMs);
  // 1000h, 1018h sub 1..4, three names (segmented: initiate and segments), 1017h.
  EXPECT_GE(uploads_only(kSaw, 9), 9u);
}

// Not the device the line expects (another product code): the judgement says so with the boot's
// letter, and, since the device answered, the names and 1017h are read all the same (an adopted
// device keeps running and its info says what it is).
TEST_F(IdentityReaderTest, AnotherDeviceIsJudgedAndStillReadInFull) {
  const auto r = reader(kSaw, {kProfile420, std::nullopt, kVendor, 0x04200002, std::nullopt, std::nullopt});
  const auto reading = read_all(r);
  const auto& c = reading.check;
  ASSERT_TRUE(c.error);
  EXPECT_EQ(c.error->code, 'M');
  EXPECT_EQ(c.error->index, 0x1018);
  EXPECT_EQ(c.error->sub, 2);
  EXPECT_NE(c.error->message.find("product code (1018h sub 2) is 0420 0004h, the line expects 0420 0002h"),
            std::string::npos)
      << c.error->message;
  EXPECT_TRUE(c.answered);
  EXPECT_EQ(c.identity.product_code, kProduct);
  EXPECT_EQ(c.identity.serial_number, kSerial);
  EXPECT_FALSE(c.identity.device_name.empty());
  ASSERT_TRUE(reading.heartbeat_producer_ms);
  EXPECT_EQ(*reading.heartbeat_producer_ms, kHeartbeatMs);
  EXPECT_GE(uploads_only(kSaw, 9), 9u);
}

// The first difference counts, in the boot's order: a device type of another profile (C) before a
// vendor-ID that differs too (D).
TEST_F(IdentityReaderTest, TheDeviceTypeIsJudgedFirst) {
  const auto c = check(
      reader(kSaw, {0x019E /* 414 */, std::nullopt, 0x11111111, std::nullopt, std::nullopt, std::nullopt}));
  ASSERT_TRUE(c.error);
  EXPECT_EQ(c.error->code, 'C');
  EXPECT_EQ(c.error->index, 0x1000);
  EXPECT_TRUE(c.answered);
  EXPECT_EQ(c.identity.device_type, kDeviceType);
  EXPECT_EQ(c.identity.vendor_id, kVendor);
  const auto d = check(reader(kSaw, {kProfile420, std::nullopt, 0x11111111, std::nullopt, std::nullopt, std::nullopt}));
  ASSERT_TRUE(d.error);
  EXPECT_EQ(d.error->code, 'D');
}

// A device without the optional objects (1018h sub 2..4, 1008h..100Ah, 1017h): each one it lacks is
// a remark, none an error, while the line expects none of them; a product code the line expects and
// the device lacks is the boot's M.
TEST_F(IdentityReaderTest, OptionalObjectsADeviceLacksAreRemarks) {
  const auto reading = read_all(
      reader(kBare, {kProfile420, std::nullopt, 0x1234, std::nullopt, std::nullopt, std::nullopt}));
  const auto& c = reading.check;
  EXPECT_FALSE(c.error) << c.error->message;
  EXPECT_TRUE(c.answered);
  EXPECT_EQ(c.identity.vendor_id, 0x1234u);
  EXPECT_EQ(c.identity.product_code, 0u);
  for (const char* remark :
       {"product code: not implemented", "revision number: not implemented", "serial number: not implemented",
        "device name: not implemented", "hardware version: not implemented", "software version: not implemented",
        "heartbeat producer time 1017h: not implemented"}) {
    EXPECT_NE(c.identity.remarks.find(remark), std::string::npos) << remark << " in: " << c.identity.remarks;
  }
  EXPECT_FALSE(reading.heartbeat_producer_ms);

  const auto m = check(reader(kBare, {kProfile420, std::nullopt, 0x1234, 0x04200004, std::nullopt, std::nullopt}));
  ASSERT_TRUE(m.error);
  EXPECT_EQ(m.error->code, 'M');
  EXPECT_EQ(m.error->actual, "absent");
  EXPECT_TRUE(m.answered);
  EXPECT_GE(uploads_only(kBare, 9), 9u);
}

// Nobody at the node-ID: B (no answer to 1000h, the client's timeout), not answered, and nothing
// more is asked after it.
TEST_F(IdentityReaderTest, NoDeviceIsBAndNothingMoreIsAsked) {
  const auto reading = read_all(
      reader(kNobody, {kProfile420, std::nullopt, std::nullopt, std::nullopt, std::nullopt, std::nullopt}));
  const auto& c = reading.check;
  ASSERT_TRUE(c.error);
  EXPECT_EQ(c.error->code, 'B');
  EXPECT_EQ(c.error->abort_code, 0x05040000u);  // CiA 301: SDO protocol timed out
  EXPECT_FALSE(c.answered);
  EXPECT_FALSE(reading.heartbeat_producer_ms);
  // The initiate upload of 1000h, then the client's abort of it (on its way to the spy when the
  // reading ended): nothing else, and the reading is over.
  ASSERT_TRUE(spy_->wait_until([](const auto& all) {
    return std::count_if(all.begin(), all.end(), [](const auto& f) { return f.id == 0x600u + kNobody; }) >= 2;
  }));
  const auto frames = spy_->frames(0x600u + kNobody);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].data[0], 0x40);
  EXPECT_EQ(frames[0].data[1] | frames[0].data[2] << 8, 0x1000);
  EXPECT_EQ(frames[1].data[0], 0x80);
}
