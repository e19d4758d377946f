// SDO against real sockets: a client bus loop and a server bus loop on one virtual bus, plus a
// passive member (the tap) that sees every frame and, in some tests, plays a misbehaving server.
// Golden frames are written by hand from CiA 301 (docs: cia301-essentials.md, SDO section).

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <future>
#include <latch>
#include <limits>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "can/virtual_bus.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/data_type.hpp"
#include "canopen/object_value.hpp"
#include "canopen/sdo_abort.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sdo_error.hpp"
#include "canopen/sdo_server.hpp"

namespace lb::canopen {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using Bytes = std::vector<std::uint8_t>;
using can::CanFrame;

constexpr std::uint8_t kNode = 5;

// ---- bus helpers ---------------------------------------------------------------------------------

// Unique per process and test, so parallel ctest runs never share a hub.
std::string bus_name() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = "sdo" + std::to_string(::getpid()) + "-" + info->test_suite_name() + "-" + info->name();
  name.resize(std::min<std::size_t>(name.size(), 91));
  return name;
}

std::unique_ptr<can::Bus> open_member(const std::string& name) {
  auto bus = can::VirtualBus::open(name);
  if (!bus) throw std::runtime_error(bus.error().message);
  return std::move(*bus);
}

std::optional<CanFrame> next_frame(can::Bus& bus, std::chrono::milliseconds timeout = 3000ms) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    auto r = bus.receive();
    if (!r) throw std::runtime_error(r.error().message);
    if (*r) return **r;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return std::nullopt;
    pollfd p{bus.fd(), POLLIN, 0};
    ::poll(&p, 1, static_cast<int>(left));
  }
}

std::string hex(std::span<const std::uint8_t> bytes) { return fmt::format("{:02X}", fmt::join(bytes, " ")); }

CanFrame sdo_frame(std::uint32_t id, Bytes data) {
  CanFrame f;
  f.id = id;
  f.len = static_cast<std::uint8_t>(data.size());
  std::copy(data.begin(), data.end(), f.data.begin());
  return f;
}

struct Golden {
  std::uint32_t id;
  Bytes data;
};

// The next frames on the bus must be exactly these (id and all eight bytes).
void expect_traffic(can::Bus& tap, const std::vector<Golden>& want) {
  for (std::size_t i = 0; i < want.size(); ++i) {
    auto f = next_frame(tap);
    ASSERT_TRUE(f) << "frame " << i << " (" << fmt::format("{:03X}", want[i].id) << " " << hex(want[i].data)
                   << ") never came";
    EXPECT_EQ(fmt::format("{:03X} {}", f->id, hex(f->payload())),
              fmt::format("{:03X} {}", want[i].id, hex(want[i].data)))
        << "frame " << i;
  }
}

void expect_quiet(can::Bus& tap, std::chrono::milliseconds for_ = 100ms) {
  auto f = next_frame(tap, for_);
  EXPECT_FALSE(f) << "unexpected frame " << fmt::format("{:03X} {}", f->id, hex(f->payload()));
}

template <class T>
T wait(std::future<T>& f, std::chrono::milliseconds timeout = 5000ms) {
  if (f.wait_for(timeout) != std::future_status::ready) throw std::runtime_error("no completion in time");
  return f.get();
}

// Runs f on the loop thread and returns its result (dictionaries belong to their loop).
template <class F>
auto on_loop(BusLoop& loop, F f) {
  using R = decltype(f());
  auto p = std::make_shared<std::promise<R>>();  // the loop thread may still be in set_value when we return
  auto fut = p->get_future();
  loop.post([p, f] { p->set_value(f()); });
  return wait(fut);
}

bool contains(const std::string& s, std::string_view part) { return s.find(part) != std::string::npos; }

// Completion order of callbacks, from the loop thread to the test thread.
class Recorder {
 public:
  void add(int v) {
    // Notified under the lock: the waiter may destroy the recorder as soon as it sees the value.
    std::lock_guard lock(m_);
    seen_.push_back(v);
    cv_.notify_all();
  }
  std::vector<int> wait_for(std::size_t n, std::chrono::milliseconds timeout = 5000ms) {
    std::unique_lock lock(m_);
    cv_.wait_for(lock, timeout, [&] { return seen_.size() >= n; });
    return seen_;
  }
  std::vector<int> seen() {
    std::lock_guard lock(m_);
    return seen_;
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::vector<int> seen_;
};

// ---- the device every test talks to ------------------------------------------------------------

constexpr DataType kTypes2001[] = {DataType::integer8,   DataType::integer16,  DataType::integer32,
                                   DataType::integer64,  DataType::unsigned8,  DataType::unsigned16,
                                   DataType::unsigned32, DataType::unsigned64, DataType::real32,
                                   DataType::real64,     DataType::boolean};

Bytes bytes_of(std::string_view s) { return Bytes(s.begin(), s.end()); }

ObjectDictionary test_dictionary() {
  ObjectDictionary od;
  auto add = [&](std::uint16_t index, std::uint8_t sub, DataType type, ObjectAccess access, Bytes value = {},
                 std::optional<std::int64_t> min = {}, std::optional<std::int64_t> max = {}) {
    if (auto r = od.add(index, sub, type, access, std::move(value), min, max); !r) {
      throw std::runtime_error(r.error().message);
    }
  };
  add(0x1000, 0, DataType::unsigned32, ObjectAccess::ro, {0xA4, 0x01, 0x00, 0x00});
  add(0x1008, 0, DataType::visible_string, ObjectAccess::const_, bytes_of("linebridge test device"));
  for (std::uint8_t sub = 1; sub <= 11; ++sub) add(0x2001, sub, kTypes2001[sub - 1], ObjectAccess::rw);
  add(0x2002, 0, DataType::unsigned16, ObjectAccess::wo);
  add(0x2003, 0, DataType::integer16, ObjectAccess::rw, {}, -100, 100);
  add(0x2004, 0, DataType::unsigned8, ObjectAccess::rw);
  add(0x2005, 0, DataType::unsigned32, ObjectAccess::const_, {1, 0, 0, 0});
  add(0x2100, 0, DataType::visible_string, ObjectAccess::rw);
  add(0x2101, 0, DataType::octet_string, ObjectAccess::rw);
  for (std::uint16_t t = 0; t < 4; ++t) {
    add(static_cast<std::uint16_t>(0x2200 + t), 0, DataType::integer32, ObjectAccess::rw);
    add(static_cast<std::uint16_t>(0x2300 + t), 0, DataType::visible_string, ObjectAccess::rw);
  }
  // Refuses 255 the way a device refuses a write in its present state.
  (void)od.set_on_write(0x2004, 0, [](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    if (v[0] == 0xFF) return sdo_abort::cannot_store_device_state;
    return std::nullopt;
  });
  return od;
}

class Sdo : public ::testing::Test {
 protected:
  void SetUp() override {
    name_ = bus_name();
    tap_ = open_member(name_);  // first, so it sees every frame
    client_loop_ = std::make_unique<BusLoop>(open_member(name_));
    server_loop_ = std::make_unique<BusLoop>(open_member(name_));
  }
  void TearDown() override {
    client_loop_->stop();
    server_loop_->stop();
  }

  SdoClient& make_client(std::chrono::milliseconds timeout = SdoClient::kDefaultTimeout) {
    client_ = std::make_unique<SdoClient>(*client_loop_, timeout);
    return *client_;
  }
  SdoServer& add_server(std::uint8_t node) {
    servers_.push_back(std::make_unique<SdoServer>(*server_loop_, node, test_dictionary()));
    return *servers_.back();
  }
  void start() {
    client_loop_->start();
    server_loop_->start();
  }
  // The standard set-up: a client, the server of node 5, both running.
  SdoClient& client_and_server(std::chrono::milliseconds timeout = SdoClient::kDefaultTimeout) {
    add_server(kNode);
    make_client(timeout);
    start();
    return *client_;
  }

  std::string name_;
  std::unique_ptr<can::Bus> tap_;
  std::unique_ptr<BusLoop> client_loop_;
  std::unique_ptr<BusLoop> server_loop_;
  std::unique_ptr<SdoClient> client_;
  std::vector<std::unique_ptr<SdoServer>> servers_;
};

// ---- abort codes and values ----------------------------------------------------------------------

TEST(SdoAbort, EveryCodeHasItsMeaning) {
  EXPECT_EQ(sdo_abort_meaning(0x05030000), "toggle bit not alternated");
  EXPECT_EQ(sdo_abort_meaning(0x05040000), "SDO protocol timed out");
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x05040001)), "command specifier"));
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x06010001)), "write-only"));
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x06010002)), "read-only"));
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x06020000)), "does not exist"));
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x06090011)), "sub-index"));
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x06090031)), "too high"));
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x06090032)), "too low"));
  EXPECT_TRUE(contains(std::string(sdo_abort_meaning(0x08000022)), "present device state"));
  for (std::uint32_t code : {0x06010000u, 0x06040041u, 0x06040042u, 0x06070010u, 0x06090030u, 0x08000000u, 0x08000020u,
                             0x08000021u, 0x05040005u, 0x06060000u, 0x060A0023u}) {
    EXPECT_NE(sdo_abort_meaning(code), "unknown abort code") << fmt::format("{:08X}", code);
  }
  EXPECT_EQ(sdo_abort_meaning(0x12345678), "unknown abort code");
  EXPECT_EQ(sdo_abort_meaning(0), "unknown abort code");
}

TEST(SdoError, NamesNodeObjectCodeMeaningAndWho) {
  const auto e = make_sdo_error(5, 0x6000, 0x02, 0x06090031, SdoErrorOrigin::server);
  EXPECT_EQ(e.abort_code, 0x06090031u);
  EXPECT_EQ(e.message, "SDO node 5 6000h:02: aborted by the server: 06090031h value of parameter written too high");
  const auto t = make_sdo_error(5, 0x1008, 0, 0x05040000, SdoErrorOrigin::client, "no response within 1000 ms");
  EXPECT_TRUE(contains(t.message, "aborted by the client")) << t.message;
  EXPECT_TRUE(contains(t.message, "(no response within 1000 ms)")) << t.message;
  const auto l = make_sdo_error(5, 0x1008, 0, 0x08000000, SdoErrorOrigin::local, "client destroyed");
  EXPECT_TRUE(contains(l.message, "failed locally")) << l.message;
}

TEST(ObjectValue, EncodesLittleEndian) {
  struct Case {
    DataType type;
    ObjectValue value;
    Bytes bytes;
  };
  const std::vector<Case> cases = {
      {DataType::boolean, std::uint64_t{1}, {0x01}},
      {DataType::integer8, std::int64_t{-2}, {0xFE}},
      {DataType::integer16, std::int64_t{-2}, {0xFE, 0xFF}},
      {DataType::integer16, std::uint64_t{0x1234}, {0x34, 0x12}},
      {DataType::integer32, std::int64_t{-100000}, {0x60, 0x79, 0xFE, 0xFF}},
      {DataType::integer64, std::int64_t{std::numeric_limits<std::int64_t>::min()}, {0, 0, 0, 0, 0, 0, 0, 0x80}},
      {DataType::unsigned8, std::int64_t{200}, {0xC8}},
      {DataType::unsigned16, std::uint64_t{65535}, {0xFF, 0xFF}},
      {DataType::unsigned32, std::uint64_t{0x12345678}, {0x78, 0x56, 0x34, 0x12}},
      {DataType::unsigned64, std::uint64_t{0x0123456789ABCDEF}, {0xEF, 0xCD, 0xAB, 0x89, 0x67, 0x45, 0x23, 0x01}},
      {DataType::real32, 1.5, {0x00, 0x00, 0xC0, 0x3F}},
      {DataType::real32, std::int64_t{1}, {0x00, 0x00, 0x80, 0x3F}},
      {DataType::real64, -0.5, {0, 0, 0, 0, 0, 0, 0xE0, 0xBF}},
      {DataType::visible_string, std::string("ab"), {'a', 'b'}},
      {DataType::octet_string, Bytes{0, 1, 2}, {0, 1, 2}},
      {DataType::octet_string, std::string("x"), {'x'}},
  };
  for (const auto& c : cases) {
    auto r = encode(c.type, c.value);
    ASSERT_TRUE(r) << to_string(c.type) << " " << to_string(c.value) << ": " << r.error().message;
    EXPECT_EQ(hex(*r), hex(c.bytes)) << to_string(c.type) << " " << to_string(c.value);
  }
}

TEST(ObjectValue, RefusesMismatchesAndValuesOutOfRange) {
  struct Case {
    DataType type;
    ObjectValue value;
    std::string says;
  };
  const std::vector<Case> cases = {
      {DataType::integer16, std::string("12"), "INTEGER16 cannot take a string"},
      {DataType::unsigned16, std::int64_t{70000}, "70000 is out of range for UNSIGNED16 (0..65535)"},
      {DataType::unsigned16, std::uint64_t{70000}, "out of range for UNSIGNED16"},
      {DataType::unsigned8, std::int64_t{-1}, "out of range for UNSIGNED8"},
      {DataType::integer8, std::int64_t{128}, "out of range for INTEGER8 (-128..127)"},
      {DataType::integer8, std::int64_t{-129}, "out of range for INTEGER8"},
      {DataType::integer64, std::numeric_limits<std::uint64_t>::max(), "out of range for INTEGER64"},
      {DataType::integer32, 1.5, "INTEGER32 cannot take a real number"},
      {DataType::boolean, std::uint64_t{2}, "out of range for BOOLEAN"},
      {DataType::visible_string, Bytes{1}, "VISIBLE_STRING cannot take a byte string"},
      {DataType::real32, 1e39, "out of range for REAL32"},
      {DataType::real64, std::string("1"), "REAL64 cannot take a string"},
  };
  for (const auto& c : cases) {
    auto r = encode(c.type, c.value);
    ASSERT_FALSE(r) << to_string(c.type) << " took " << to_string(c.value);
    EXPECT_TRUE(contains(r.error().message, c.says)) << r.error().message;
  }
}

TEST(ObjectValue, DecodesByTypeWithExactLengths) {
  auto i32 = decode(DataType::integer32, Bytes{0x60, 0x79, 0xFE, 0xFF});
  ASSERT_TRUE(i32);
  EXPECT_EQ(*i32, ObjectValue{std::int64_t{-100000}});
  for (const Bytes& wrong : {Bytes{1, 2, 3}, Bytes{1, 2, 3, 4, 5}, Bytes{}}) {
    auto r = decode(DataType::integer32, wrong);
    ASSERT_FALSE(r);
    EXPECT_TRUE(contains(r.error().message, "INTEGER32 takes 4 bytes")) << r.error().message;
  }
  EXPECT_EQ(*decode(DataType::unsigned16, Bytes{0xFF, 0xFF}), ObjectValue{std::uint64_t{65535}});
  EXPECT_EQ(*decode(DataType::integer8, Bytes{0x80}), ObjectValue{std::int64_t{-128}});
  EXPECT_EQ(*decode(DataType::real32, Bytes{0x00, 0x00, 0xC0, 0x3F}), ObjectValue{1.5});
  EXPECT_EQ(*decode(DataType::real64, Bytes{0, 0, 0, 0, 0, 0, 0xE0, 0xBF}), ObjectValue{-0.5});
  EXPECT_EQ(*decode(DataType::visible_string, Bytes{'a', 'b', 0, 'c'}), ObjectValue{std::string("ab")});
  EXPECT_EQ(*decode(DataType::visible_string, Bytes{}), ObjectValue{std::string()});
  EXPECT_EQ(*decode(DataType::octet_string, Bytes{'a', 0, 'c'}), ObjectValue{Bytes({'a', 0, 'c'})});
  EXPECT_FALSE(decode(DataType::boolean, Bytes{2}));
}

TEST(ObjectValue, PrintsForLogs) {
  EXPECT_EQ(to_string(ObjectValue{std::int64_t{-7}}), "-7");
  EXPECT_EQ(to_string(ObjectValue{std::uint64_t{42}}), "42");
  EXPECT_EQ(to_string(ObjectValue{1.5}), "1.5");
  EXPECT_EQ(to_string(ObjectValue{std::string("a\"b\n")}), "\"a\\\"b\\x0A\"");
  EXPECT_EQ(to_string(ObjectValue{Bytes{0x01, 0xA2, 0xFF}}), "[01 A2 FF]");
  EXPECT_EQ(to_string(ObjectValue{Bytes{}}), "[]");
}

TEST(ObjectDictionary, KnowsTheAbortForEveryRefusal) {
  ObjectDictionary od = test_dictionary();
  EXPECT_EQ(od.read(0x3000, 0).error(), sdo_abort::no_such_object);
  EXPECT_EQ(od.read(0x2001, 0x0C).error(), sdo_abort::no_such_sub_index);
  EXPECT_EQ(od.read(0x2002, 0).error(), sdo_abort::read_of_write_only);
  EXPECT_EQ(od.write(0x1000, 0, Bytes{1, 0, 0, 0}).error(), sdo_abort::write_to_read_only);
  EXPECT_EQ(od.write(0x2005, 0, Bytes{1, 0, 0, 0}).error(), sdo_abort::write_to_read_only);
  EXPECT_EQ(od.write(0x2001, 3, Bytes{1, 0}).error(), sdo_abort::length_mismatch);
  EXPECT_EQ(od.write(0x2003, 0, Bytes{101, 0}).error(), sdo_abort::value_too_high);
  EXPECT_EQ(od.write(0x2003, 0, Bytes{0x9B, 0xFF}).error(), sdo_abort::value_too_low);  // -101
  EXPECT_TRUE(od.write(0x2003, 0, Bytes{0x9C, 0xFF}));                                  // -100
  EXPECT_EQ(od.write(0x2001, 0x0B, Bytes{2}).error(), sdo_abort::value_range_exceeded);
  EXPECT_EQ(od.write(0x2004, 0, Bytes{0xFF}).error(), sdo_abort::cannot_store_device_state);
  EXPECT_EQ(od.check_write(0x2001, 3, 8).error(), sdo_abort::length_mismatch);
  EXPECT_TRUE(od.check_write(0x2100, 0, 1000));
  EXPECT_FALSE(od.add(0x2400, 0, DataType::unsigned16, ObjectAccess::rw, Bytes{1}));
  EXPECT_TRUE(od.set(0x1000, 0, Bytes{1, 2, 3, 4}));  // the application may change read-only values
  EXPECT_EQ(hex(*od.read(0x1000, 0)), "01 02 03 04");
}

// ---- transfers against the server ----------------------------------------------------------------

// 2001h sub (of the type kTypes2001 gives it) written with value, read back and compared.
void write_and_read_back(SdoClient& client, std::uint8_t sub, const ObjectValue& value) {
  const DataType type = kTypes2001[sub - 1];
  auto w = client.write_async(kNode, 0x2001, sub, type, value);
  auto written = wait(w);
  ASSERT_TRUE(written) << written.error().message;
  auto r = client.read_async(kNode, 0x2001, sub, type);
  auto read = wait(r);
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(*read, value);
}

TEST_F(Sdo, ExpeditedWriteAndReadOfEveryType) {
  SdoClient& client = client_and_server();
  struct Case {
    std::uint8_t sub;
    ObjectValue value;
    std::uint8_t download_cs;  // 23h | (4 - size) << 2
    std::uint8_t upload_cs;    // 43h | (4 - size) << 2
    Bytes data;
  };
  const std::vector<Case> cases = {
      {0x01, std::int64_t{-2}, 0x2F, 0x4F, {0xFE}},
      {0x02, std::int64_t{-2}, 0x2B, 0x4B, {0xFE, 0xFF}},
      {0x03, std::int64_t{-100000}, 0x23, 0x43, {0x60, 0x79, 0xFE, 0xFF}},
      {0x05, std::uint64_t{200}, 0x2F, 0x4F, {0xC8}},
      {0x06, std::uint64_t{0xBEEF}, 0x2B, 0x4B, {0xEF, 0xBE}},
      {0x07, std::uint64_t{0xDEADBEEF}, 0x23, 0x43, {0xEF, 0xBE, 0xAD, 0xDE}},
      {0x09, 1.5, 0x23, 0x43, {0x00, 0x00, 0xC0, 0x3F}},
      {0x0B, std::uint64_t{1}, 0x2F, 0x4F, {0x01}},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(std::string(to_string(kTypes2001[c.sub - 1])));
    ASSERT_NO_FATAL_FAILURE(write_and_read_back(client, c.sub, c.value));

    Bytes request{c.download_cs, 0x01, 0x20, c.sub, 0, 0, 0, 0};
    Bytes response{c.upload_cs, 0x01, 0x20, c.sub, 0, 0, 0, 0};
    std::copy(c.data.begin(), c.data.end(), request.begin() + 4);
    std::copy(c.data.begin(), c.data.end(), response.begin() + 4);
    expect_traffic(*tap_, {{0x605, request},
                           {0x585, {0x60, 0x01, 0x20, c.sub, 0, 0, 0, 0}},
                           {0x605, {0x40, 0x01, 0x20, c.sub, 0, 0, 0, 0}},
                           {0x585, response}});
  }
  expect_quiet(*tap_);
}

// 64-bit values do not fit an expedited transfer: two segments, 7 bytes and 1.
TEST_F(Sdo, SixtyFourBitTypesGoSegmented) {
  SdoClient& client = client_and_server();
  struct Case {
    std::uint8_t sub;
    ObjectValue value;
    Bytes data;
  };
  const std::vector<Case> cases = {
      {0x04, std::int64_t{-2}, {0xFE, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}},
      {0x08, std::uint64_t{0x0123456789ABCDEF}, {0xEF, 0xCD, 0xAB, 0x89, 0x67, 0x45, 0x23, 0x01}},
      {0x0A, -0.5, {0, 0, 0, 0, 0, 0, 0xE0, 0xBF}},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(std::string(to_string(kTypes2001[c.sub - 1])));
    ASSERT_NO_FATAL_FAILURE(write_and_read_back(client, c.sub, c.value));

    const Bytes& d = c.data;
    const Bytes first{0x00, d[0], d[1], d[2], d[3], d[4], d[5], d[6]};
    const Bytes second_download{0x1D, d[7], 0, 0, 0, 0, 0, 0};  // t=1, n=6, c=1
    expect_traffic(*tap_, {{0x605, {0x21, 0x01, 0x20, c.sub, 0x08, 0, 0, 0}},
                           {0x585, {0x60, 0x01, 0x20, c.sub, 0, 0, 0, 0}},
                           {0x605, first},
                           {0x585, {0x20, 0, 0, 0, 0, 0, 0, 0}},
                           {0x605, second_download},
                           {0x585, {0x30, 0, 0, 0, 0, 0, 0, 0}},
                           {0x605, {0x40, 0x01, 0x20, c.sub, 0, 0, 0, 0}},
                           {0x585, {0x41, 0x01, 0x20, c.sub, 0x08, 0, 0, 0}},
                           {0x605, {0x60, 0, 0, 0, 0, 0, 0, 0}},
                           {0x585, first},
                           {0x605, {0x70, 0, 0, 0, 0, 0, 0, 0}},
                           {0x585, second_download}});
  }
}

TEST_F(Sdo, SegmentedUploadOfALongVisibleString) {
  SdoServer& server = add_server(kNode);
  std::string text;
  for (int i = 0; i < 200; ++i) text += static_cast<char>('A' + i % 26);
  ASSERT_TRUE(server.dictionary().set(0x2100, 0, bytes_of(text)));
  SdoClient& client = make_client();
  start();

  auto r = client.read_async(kNode, 0x2100, 0, DataType::visible_string);
  auto read = wait(r);
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(*read, ObjectValue{text});

  // 200 bytes: 28 full segments and one of 4 (n = 3, c = 1); toggle 0, 1, 0, ...
  expect_traffic(*tap_,
                 {{0x605, {0x40, 0x00, 0x21, 0x00, 0, 0, 0, 0}}, {0x585, {0x41, 0x00, 0x21, 0x00, 0xC8, 0, 0, 0}}});
  for (int seg = 0; seg < 29; ++seg) {
    const bool t = seg % 2 == 1;
    Bytes data{static_cast<std::uint8_t>(t ? 0x10 : 0x00)};
    if (seg == 28) data[0] = 0x07;  // t=0, n=3, c=1
    for (int i = 0; i < 7; ++i) {
      const int at = seg * 7 + i;
      data.push_back(at < 200 ? static_cast<std::uint8_t>(text[static_cast<std::size_t>(at)]) : 0);
    }
    expect_traffic(*tap_, {{0x605, {static_cast<std::uint8_t>(t ? 0x70 : 0x60), 0, 0, 0, 0, 0, 0, 0}}, {0x585, data}});
  }
  expect_quiet(*tap_);
}

TEST_F(Sdo, SegmentedDownloadOfALongOctetString) {
  SdoClient& client = client_and_server();
  Bytes value(200);
  for (std::size_t i = 0; i < value.size(); ++i) value[i] = static_cast<std::uint8_t>(i * 7 + 3);

  auto w = client.write_async(kNode, 0x2101, 0, DataType::octet_string, value);
  auto written = wait(w);
  ASSERT_TRUE(written) << written.error().message;
  EXPECT_EQ(hex(on_loop(*server_loop_, [&] { return servers_[0]->dictionary().find(0x2101, 0)->value; })), hex(value));

  expect_traffic(*tap_,
                 {{0x605, {0x21, 0x01, 0x21, 0x00, 0xC8, 0, 0, 0}}, {0x585, {0x60, 0x01, 0x21, 0x00, 0, 0, 0, 0}}});
  for (int seg = 0; seg < 29; ++seg) {
    const bool t = seg % 2 == 1;
    Bytes data{static_cast<std::uint8_t>(t ? 0x10 : 0x00)};
    if (seg == 28) data[0] = 0x07;  // t=0, n=3, c=1
    for (int i = 0; i < 7; ++i) {
      const std::size_t at = static_cast<std::size_t>(seg * 7 + i);
      data.push_back(at < value.size() ? value[at] : 0);
    }
    expect_traffic(*tap_, {{0x605, data}, {0x585, {static_cast<std::uint8_t>(t ? 0x30 : 0x20), 0, 0, 0, 0, 0, 0, 0}}});
  }

  auto r = client.upload_async(kNode, 0x2101, 0);
  auto read = wait(r);
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(hex(*read), hex(value));
}

// The command bytes around the 4-byte (expedited) and 7-byte (segment) boundaries, both ways.
TEST_F(Sdo, SegmentBoundaries) {
  SdoClient& client = client_and_server();
  struct Case {
    std::size_t size;
    std::vector<std::uint8_t> download;  // byte 0 of the client's frames
    std::vector<std::uint8_t> upload;    // byte 0 of the server's frames
  };
  const std::vector<Case> cases = {
      {0, {0x21, 0x0F}, {0x41, 0x0F}},  // one empty segment: n=7, c=1
      {1, {0x2F}, {0x4F}},
      {4, {0x23}, {0x43}},
      {5, {0x21, 0x05}, {0x41, 0x05}},                           // n=2, c=1
      {7, {0x21, 0x01}, {0x41, 0x01}},                           // n=0, c=1
      {8, {0x21, 0x00, 0x1D}, {0x41, 0x00, 0x1D}},               // then t=1, n=6, c=1
      {14, {0x21, 0x00, 0x11}, {0x41, 0x00, 0x11}},              // then t=1, n=0, c=1
      {15, {0x21, 0x00, 0x10, 0x0D}, {0x41, 0x00, 0x10, 0x0D}},  // then t=0, n=6, c=1
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(fmt::format("{} bytes", c.size));
    Bytes value(c.size);
    for (std::size_t i = 0; i < c.size; ++i) value[i] = static_cast<std::uint8_t>(0xA0 + i);

    auto w = client.download_async(kNode, 0x2101, 0, value);
    auto written = wait(w);
    ASSERT_TRUE(written) << written.error().message;
    std::vector<std::uint8_t> sent, answered;
    for (std::size_t i = 0; i < 2 * c.download.size(); ++i) {
      auto f = next_frame(*tap_);
      ASSERT_TRUE(f);
      (f->id == 0x605 ? sent : answered).push_back(f->data[0]);
      if (i == 0 && c.download[0] == 0x21) {
        EXPECT_EQ(f->data[4], c.size);  // size indicated
      }
    }
    EXPECT_EQ(hex(sent), hex(c.download));

    auto r = client.upload_async(kNode, 0x2101, 0);
    auto read = wait(r);
    ASSERT_TRUE(read) << read.error().message;
    EXPECT_EQ(hex(*read), hex(value));
    sent.clear();
    answered.clear();
    std::size_t data_bytes = 0;
    for (std::size_t i = 0; i < 2 * c.upload.size(); ++i) {
      auto f = next_frame(*tap_);
      ASSERT_TRUE(f);
      (f->id == 0x605 ? sent : answered).push_back(f->data[0]);
      if (f->id == 0x585 && i > 1) data_bytes += 7 - ((f->data[0] >> 1) & 7);
    }
    EXPECT_EQ(hex(answered), hex(c.upload));
    if (c.upload[0] == 0x41) {
      EXPECT_EQ(data_bytes, c.size);
    }
  }
  expect_quiet(*tap_);
}

TEST_F(Sdo, EveryServerAbortSurfacesWithCodeAndMeaning) {
  SdoClient& client = client_and_server();
  struct Case {
    std::string what;
    std::uint16_t index;
    std::uint8_t sub;
    std::optional<Bytes> write;  // nullopt: read
    std::uint32_t code;
    std::string meaning;
  };
  const std::vector<Case> cases = {
      {"read of write-only", 0x2002, 0, std::nullopt, 0x06010001, "attempt to read a write-only object"},
      {"write to read-only", 0x1000, 0, Bytes{1, 0, 0, 0}, 0x06010002, "attempt to write a read-only object"},
      {"write to const", 0x2005, 0, Bytes{2, 0, 0, 0}, 0x06010002, "read-only"},
      {"no such object", 0x3000, 0, std::nullopt, 0x06020000, "object does not exist"},
      {"no such object (write)", 0x3000, 1, Bytes{1}, 0x06020000, "object does not exist"},
      {"no such sub-index", 0x2001, 0x0C, std::nullopt, 0x06090011, "sub-index does not exist"},
      {"expedited length mismatch", 0x2001, 0x03, Bytes{1, 2}, 0x06070010, "length of service parameter"},
      {"segmented length mismatch", 0x2001, 0x03, Bytes{1, 2, 3, 4, 5, 6}, 0x06070010, "does not match"},
      {"BOOLEAN 2", 0x2001, 0x0B, Bytes{2}, 0x06090030, "value range of parameter exceeded"},
      {"above max", 0x2003, 0, Bytes{101, 0}, 0x06090031, "written too high"},
      {"below min", 0x2003, 0, Bytes{0x9B, 0xFF}, 0x06090032, "written too low"},
      {"refused by the device", 0x2004, 0, Bytes{0xFF}, 0x08000022, "because of the present device state"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    std::optional<SdoError> error;
    if (c.write) {
      auto f = client.download_async(kNode, c.index, c.sub, *c.write);
      auto r = wait(f);
      ASSERT_FALSE(r);
      error = r.error();
    } else {
      auto f = client.upload_async(kNode, c.index, c.sub);
      auto r = wait(f);
      ASSERT_FALSE(r);
      error = r.error();
    }
    EXPECT_EQ(error->abort_code, c.code);
    EXPECT_TRUE(contains(error->message, fmt::format("{:08X}h", c.code))) << error->message;
    EXPECT_TRUE(contains(error->message, c.meaning)) << error->message;
    EXPECT_TRUE(contains(error->message, "aborted by the server")) << error->message;
    EXPECT_TRUE(contains(error->message, fmt::format("node 5 {:04X}h:{:02X}", c.index, c.sub))) << error->message;
  }
  // The values refused are not stored, and the abort frame is the one CiA 301 defines.
  auto r = client.read_async(kNode, 0x2003, 0, DataType::integer16);
  EXPECT_EQ(*wait(r), ObjectValue{std::int64_t{0}});
  while (next_frame(*tap_, 100ms)) {
  }
  auto f = client.upload_async(kNode, 0x3000, 0);
  (void)wait(f);
  expect_traffic(*tap_, {{0x605, {0x40, 0x00, 0x30, 0x00, 0, 0, 0, 0}},
                         {0x585, {0x80, 0x00, 0x30, 0x00, 0x00, 0x00, 0x02, 0x06}}});
}

TEST_F(Sdo, TypedReadOfTheWrongSizeFailsLocally) {
  SdoClient& client = client_and_server();
  auto f = client.read_async(kNode, 0x2001, 0x02, DataType::integer32);  // an INTEGER16
  auto r = wait(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::length_mismatch);
  EXPECT_TRUE(contains(r.error().message, "failed locally")) << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "INTEGER32 takes 4 bytes, got 2")) << r.error().message;

  auto w = client.write_async(kNode, 0x2001, 0x06, DataType::unsigned16, std::int64_t{70000});
  auto wr = wait(w);
  ASSERT_FALSE(wr);
  EXPECT_EQ(wr.error().abort_code, sdo_abort::general_error);
  EXPECT_TRUE(contains(wr.error().message, "70000 is out of range for UNSIGNED16")) << wr.error().message;

  auto n = client.upload_async(0, 0x1000, 0);
  auto nr = wait(n);
  ASSERT_FALSE(nr);
  EXPECT_TRUE(contains(nr.error().message, "node-ID 0 is not 1..127")) << nr.error().message;
  // Refused before the bus: only the INTEGER16 upload went out.
  expect_traffic(*tap_, {{0x605, {0x40, 0x01, 0x20, 0x02, 0, 0, 0, 0}}, {0x585, {0x4B, 0x01, 0x20, 0x02, 0, 0, 0, 0}}});
  expect_quiet(*tap_);
}

// ---- timeouts and misbehaving servers (the tap plays the server) ---------------------------------

TEST_F(Sdo, TimeoutWithoutServerAbortsOnTheBus) {
  SdoClient& client = make_client(100ms);
  start();
  const auto t0 = Clock::now();
  auto first = client.upload_async(9, 0x1000, 0);
  auto second = client.download_async(9, 0x2000, 1, Bytes{1, 2});
  auto r = wait(first);
  const auto elapsed = Clock::now() - t0;
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::timed_out);
  EXPECT_TRUE(contains(r.error().message, "aborted by the client: 05040000h SDO protocol timed out"))
      << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "no response within 100 ms")) << r.error().message;
  EXPECT_GE(elapsed, 100ms);
  auto r2 = wait(second);  // the queue goes on after a timeout
  ASSERT_FALSE(r2);
  EXPECT_EQ(r2.error().abort_code, sdo_abort::timed_out);

  expect_traffic(*tap_, {{0x609, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}},
                         {0x609, {0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05}},
                         {0x609, {0x2B, 0x00, 0x20, 0x01, 1, 2, 0, 0}},
                         {0x609, {0x80, 0x00, 0x20, 0x01, 0x00, 0x00, 0x04, 0x05}}});
  expect_quiet(*tap_);
}

// Diagnostics' SDO duration histogram (SdoClient::durations): per node, every transfer from its
// first frame to its end. A read the server answers at once is within 1 s; a timeout of 100 ms
// takes at least that, and lands in no bucket below 100 ms.
TEST_F(Sdo, DurationsArePerNodeFromTheFirstFrameToTheEnd) {
  SdoClient& client = client_and_server(100ms);
  const auto bucket = [](double bound) {
    const auto& b = SdoClient::kDurationBounds;
    return static_cast<std::size_t>(std::find(b.begin(), b.end(), bound) - b.begin());
  };
  EXPECT_EQ(client.durations(kNode).count(), 0u);
  auto read = client.upload_async(kNode, 0x1000, 0);
  ASSERT_TRUE(wait(read));
  auto lost = client.upload_async(9, 0x1000, 0);  // nobody answers for node 9
  ASSERT_FALSE(wait(lost));
  const auto answered = client.durations(kNode);
  EXPECT_EQ(answered.count(), 1u);
  EXPECT_EQ(answered.cumulative(bucket(1.0)), 1u);
  const auto timed_out = client.durations(9);
  EXPECT_EQ(timed_out.count(), 1u);
  EXPECT_EQ(timed_out.cumulative(bucket(0.05)), 0u) << "a 100 ms timeout measured shorter than 50 ms";
  EXPECT_GE(timed_out.sum(), 0.1);
  EXPECT_EQ(client.durations(6).count(), 0u);
}

// The timeout is per step: a slow server that answers every step in time never times out.
TEST_F(Sdo, TimeoutCountsPerStep) {
  SdoClient& client = make_client(300ms);
  start();
  auto f = client.upload_async(7, 0x1008, 0);
  const std::vector<Bytes> answers = {{0x41, 0x08, 0x10, 0x00, 0x0A, 0, 0, 0},
                                      {0x00, 'a', 'b', 'c', 'd', 'e', 'f', 'g'},
                                      {0x19, 'h', 'i', 'j', 0, 0, 0, 0}};  // t=1, n=4, c=1
  for (const Bytes& a : answers) {
    auto req = next_frame(*tap_);
    ASSERT_TRUE(req);
    std::this_thread::sleep_for(200ms);
    ASSERT_TRUE(tap_->send(sdo_frame(0x587, a)));
  }
  auto r = wait(f);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(std::string(r->begin(), r->end()), "abcdefghij");
}

TEST_F(Sdo, WrongToggleFromServerIsAborted) {
  SdoClient& client = make_client();
  start();
  auto f = client.upload_async(7, 0x2000, 0);
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x41, 0x00, 0x20, 0x00, 0x0E, 0, 0, 0})));
  expect_traffic(*tap_, {{0x607, {0x60, 0, 0, 0, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x00, 1, 2, 3, 4, 5, 6, 7})));
  expect_traffic(*tap_, {{0x607, {0x70, 0, 0, 0, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x01, 8, 9, 10, 11, 12, 13, 14})));  // toggle 0 again
  expect_traffic(*tap_, {{0x607, {0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x03, 0x05}}});
  auto r = wait(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::toggle_bit_not_alternated);
  EXPECT_TRUE(contains(r.error().message, "aborted by the client: 05030000h toggle bit not alternated"))
      << r.error().message;
}

TEST_F(Sdo, WrongToggleInADownloadResponseIsAborted) {
  SdoClient& client = make_client();
  start();
  auto f = client.download_async(7, 0x2101, 0, Bytes(10, 0x55));
  expect_traffic(*tap_, {{0x607, {0x21, 0x01, 0x21, 0x00, 0x0A, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x60, 0x01, 0x21, 0x00, 0, 0, 0, 0})));
  expect_traffic(*tap_, {{0x607, {0x00, 0x55, 0x55, 0x55, 0x55, 0x55, 0x55, 0x55}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x30, 0, 0, 0, 0, 0, 0, 0})));  // toggle 1 for segment 0
  expect_traffic(*tap_, {{0x607, {0x80, 0x01, 0x21, 0x00, 0x00, 0x00, 0x03, 0x05}}});
  auto r = wait(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::toggle_bit_not_alternated);
}

TEST_F(Sdo, UnexpectedCommandSpecifierFromServerIsAborted) {
  SdoClient& client = make_client();
  start();
  auto f = client.upload_async(7, 0x2000, 3);
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x20, 0x03, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x60, 0x00, 0x20, 0x03, 0, 0, 0, 0})));  // a download response
  expect_traffic(*tap_, {{0x607, {0x80, 0x00, 0x20, 0x03, 0x01, 0x00, 0x04, 0x05}}});
  auto r = wait(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::invalid_command_specifier);
  EXPECT_TRUE(contains(r.error().message, "aborted by the client")) << r.error().message;
}

TEST_F(Sdo, ResponsesWithNothingInFlightAreIgnored) {
  SdoClient& client = make_client();
  start();
  auto serve = [&](std::uint8_t node, Bytes answer) {
    auto req = next_frame(*tap_);
    ASSERT_TRUE(req);
    ASSERT_EQ(req->id, 0x600u + node);
    ASSERT_TRUE(tap_->send(sdo_frame(0x580 + node, std::move(answer))));
  };
  auto a = client.upload_async(7, 0x2000, 0);
  serve(7, {0x4B, 0x00, 0x20, 0x00, 0x11, 0x22, 0, 0});
  auto ra = wait(a);
  ASSERT_TRUE(ra) << ra.error().message;
  EXPECT_EQ(hex(*ra), "11 22");

  // A late duplicate, then a transfer with node 8 as a fence: the client's loop handles frames in
  // bus order, so once node 8's answer is in, the duplicate has been seen (and must be ignored).
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x4B, 0x00, 0x20, 0x00, 0x33, 0x44, 0, 0})));
  auto fence = client.upload_async(8, 0x2000, 0);
  serve(8, {0x4F, 0x00, 0x20, 0x00, 0x01, 0, 0, 0});
  ASSERT_TRUE(wait(fence));

  auto b = client.upload_async(7, 0x2000, 0);
  serve(7, {0x4B, 0x00, 0x20, 0x00, 0x55, 0x66, 0, 0});
  auto rb = wait(b);
  ASSERT_TRUE(rb) << rb.error().message;
  EXPECT_EQ(hex(*rb), "55 66");
}

// A slow device's answer to a transfer that timed out arrives while the next one (another object)
// is in flight: it is not that transfer's answer and must not abort it (it did: "response names
// another object", general error). The next transfer gets its own answer.
TEST_F(Sdo, ALateAnswerToAnEarlierTransferDoesNotAbortTheNext) {
  SdoClient& client = make_client(100ms);
  start();
  auto first = client.upload_async(7, 0x1000, 0);
  auto second = client.upload_async(7, 0x1018, 1);
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}}});
  // No answer within 100 ms: the client aborts the first and sends the second.
  expect_traffic(*tap_, {{0x607, {0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05}},
                         {0x607, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}}});
  auto r1 = wait(first);
  ASSERT_FALSE(r1);
  EXPECT_EQ(r1.error().abort_code, sdo_abort::timed_out);
  // Now the late answer to 1000h, and a late abort naming it, then the real answer to 1018h sub 1.
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x43, 0x00, 0x10, 0x00, 0xA4, 0x01, 0x00, 0x00})));
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05})));
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x43, 0x18, 0x10, 0x01, 0x00, 0x00, 0x42, 0x4C})));
  auto r2 = wait(second);
  ASSERT_TRUE(r2) << r2.error().message;
  EXPECT_EQ(hex(*r2), "00 00 42 4C");
  expect_quiet(*tap_);  // the client aborted nothing
}

// ---- stops (Limit::stops, the feeder box's 600Eh): never behind another transfer -----------------

// A stop as FeederGateway::write_now sends it, its answer as a future.
std::future<SdoClient::DownloadResult> stop_async(SdoClient& client, std::uint8_t node, std::uint16_t index,
                                                  std::uint8_t sub, Bytes data) {
  auto p = std::make_shared<std::promise<SdoClient::DownloadResult>>();
  auto f = p->get_future();
  client.download(
      node, index, sub, std::move(data), [p](SdoClient::DownloadResult r) { p->set_value(std::move(r)); },
      SdoClient::Limit{.max_waiting = 8, .stops = true});
  return f;
}

// The fault campaign's case: a boot read in flight to a device that does not answer held the
// operator's stop back until the read's timeout (up to 1 s). Now the read is aborted on the bus
// (08000000h), the stop goes out at once, and the read is restarted after it, ahead of what waited.
TEST_F(Sdo, AStopPreemptsAReadWaitingForASilentServer) {
  SdoClient& client = make_client();  // 1000 ms
  start();
  auto read = client.upload_async(7, 0x1000, 0);
  auto waiting = client.upload_async(7, 0x1018, 1);
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}}});
  const auto t0 = Clock::now();
  auto stop = stop_async(client, 7, 0x600E, 0, Bytes{0x01});
  expect_traffic(*tap_, {{0x607, {0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x08}},
                         {0x607, {0x2F, 0x0E, 0x60, 0x00, 0x01, 0, 0, 0}}});
  EXPECT_LT(Clock::now() - t0, 100ms) << "a stop accepted must be on the bus within 100 ms";
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x60, 0x0E, 0x60, 0x00, 0, 0, 0, 0})));
  auto rs = wait(stop);
  ASSERT_TRUE(rs) << rs.error().message;
  EXPECT_EQ(read.wait_for(0ms), std::future_status::timeout) << "the preempted read completed";
  // The read again from its first step, then the request that waited behind it.
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x43, 0x00, 0x10, 0x00, 0xA4, 0x01, 0x00, 0x00})));
  auto rr = wait(read);
  ASSERT_TRUE(rr) << rr.error().message;
  EXPECT_EQ(hex(*rr), "A4 01 00 00");
  expect_traffic(*tap_, {{0x607, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x43, 0x18, 0x10, 0x01, 0x00, 0x00, 0x42, 0x4C})));
  auto rw = wait(waiting);
  ASSERT_TRUE(rw) << rw.error().message;
  expect_quiet(*tap_);
}

// The server's answer to the preempted read crosses the client's abort. It names the very object
// the stop writes (only its kind tells it apart), and an older late answer names another object:
// neither completes nor aborts the stop, which takes its own answer.
TEST_F(Sdo, ALateAnswerToThePreemptedReadDoesNotCompleteTheStop) {
  SdoClient& client = make_client();
  start();
  auto read = client.upload_async(7, 0x600E, 0);
  expect_traffic(*tap_, {{0x607, {0x40, 0x0E, 0x60, 0x00, 0, 0, 0, 0}}});
  auto stop = stop_async(client, 7, 0x600E, 0, Bytes{0x01});
  expect_traffic(*tap_, {{0x607, {0x80, 0x0E, 0x60, 0x00, 0x00, 0x00, 0x00, 0x08}},
                         {0x607, {0x2F, 0x0E, 0x60, 0x00, 0x01, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x4F, 0x0E, 0x60, 0x00, 0x00, 0, 0, 0})));
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x43, 0x00, 0x10, 0x00, 0xA4, 0x01, 0x00, 0x00})));
  expect_quiet(*tap_, 200ms);  // nothing aborted
  EXPECT_EQ(stop.wait_for(0ms), std::future_status::timeout) << "a late answer completed the stop";
  EXPECT_EQ(read.wait_for(0ms), std::future_status::timeout);
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x60, 0x0E, 0x60, 0x00, 0, 0, 0, 0})));
  auto rs = wait(stop);
  ASSERT_TRUE(rs) << rs.error().message;
  expect_traffic(*tap_, {{0x607, {0x40, 0x0E, 0x60, 0x00, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x4F, 0x0E, 0x60, 0x00, 0x01, 0, 0, 0})));
  auto rr = wait(read);
  ASSERT_TRUE(rr) << rr.error().message;
  EXPECT_EQ(hex(*rr), "01");
  expect_quiet(*tap_);
}

// An operator's burst: NMT reset, then the stop. The resetting device misses the first attempt;
// the client sends the stop again and the device, booted, answers it: accepted.
TEST_F(Sdo, AStopWithoutAnswerIsSentAgain) {
  SdoClient& client = make_client(200ms);
  start();
  auto stop = stop_async(client, 7, 0x600E, 0, Bytes{0x01});
  expect_traffic(*tap_, {{0x607, {0x2F, 0x0E, 0x60, 0x00, 0x01, 0, 0, 0}},
                         {0x607, {0x80, 0x0E, 0x60, 0x00, 0x00, 0x00, 0x04, 0x05}},
                         {0x607, {0x2F, 0x0E, 0x60, 0x00, 0x01, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x60, 0x0E, 0x60, 0x00, 0, 0, 0, 0})));
  auto r = wait(stop);
  ASSERT_TRUE(r) << r.error().message;
  expect_quiet(*tap_, 300ms);
}

// Three attempts, then the timeout: refused with 05040000h, as any request.
TEST_F(Sdo, AStopNeverAnsweredTimesOutAfterThreeAttempts) {
  SdoClient& client = make_client(100ms);
  start();
  const auto t0 = Clock::now();
  auto stop = stop_async(client, 7, 0x600E, 0, Bytes{0x01});
  auto r = wait(stop);
  EXPECT_GE(Clock::now() - t0, 300ms);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::timed_out);
  for (int i = 0; i < 3; ++i) {
    expect_traffic(*tap_, {{0x607, {0x2F, 0x0E, 0x60, 0x00, 0x01, 0, 0, 0}},
                           {0x607, {0x80, 0x0E, 0x60, 0x00, 0x00, 0x00, 0x04, 0x05}}});
  }
  expect_quiet(*tap_);
}

// ---- the server against raw frames ---------------------------------------------------------------

TEST_F(Sdo, ServerRefusesBadCommandSpecifiersAndToggles) {
  add_server(kNode);
  start();
  auto exchange = [&](Bytes request, Bytes response) {
    ASSERT_TRUE(tap_->send(sdo_frame(0x605, std::move(request))));
    expect_traffic(*tap_, {{0x585, std::move(response)}});
  };
  // ccs 7 does not exist; ccs 5 and 6 (block transfer) are not supported.
  exchange({0xE0, 0x00, 0x20, 0x01, 0, 0, 0, 0}, {0x80, 0x00, 0x20, 0x01, 0x01, 0x00, 0x04, 0x05});
  exchange({0xA0, 0x08, 0x10, 0x00, 0, 0, 0, 0}, {0x80, 0x08, 0x10, 0x00, 0x01, 0x00, 0x04, 0x05});
  exchange({0xC2, 0x08, 0x10, 0x00, 0, 0, 0, 0}, {0x80, 0x08, 0x10, 0x00, 0x01, 0x00, 0x04, 0x05});
  // Segments without a transfer.
  exchange({0x60, 0, 0, 0, 0, 0, 0, 0}, {0x80, 0x00, 0x00, 0x00, 0x01, 0x00, 0x04, 0x05});
  exchange({0x00, 1, 2, 3, 4, 5, 6, 7}, {0x80, 0x00, 0x00, 0x00, 0x01, 0x00, 0x04, 0x05});
  // Download of 14 bytes whose first segment carries toggle 1.
  exchange({0x21, 0x01, 0x21, 0x00, 0x0E, 0, 0, 0}, {0x60, 0x01, 0x21, 0x00, 0, 0, 0, 0});
  exchange({0x10, 1, 2, 3, 4, 5, 6, 7}, {0x80, 0x01, 0x21, 0x00, 0x00, 0x00, 0x03, 0x05});
  // Upload whose second segment request repeats toggle 0.
  exchange({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}, {0x41, 0x08, 0x10, 0x00, 0x16, 0, 0, 0});  // 22 bytes
  exchange({0x60, 0, 0, 0, 0, 0, 0, 0}, {0x00, 'l', 'i', 'n', 'e', 'b', 'r', 'i'});
  exchange({0x60, 0, 0, 0, 0, 0, 0, 0}, {0x80, 0x08, 0x10, 0x00, 0x00, 0x00, 0x03, 0x05});
  // A segment of an upload during a download is as wrong as none.
  exchange({0x21, 0x01, 0x21, 0x00, 0x0E, 0, 0, 0}, {0x60, 0x01, 0x21, 0x00, 0, 0, 0, 0});
  exchange({0x60, 0, 0, 0, 0, 0, 0, 0}, {0x80, 0x01, 0x21, 0x00, 0x01, 0x00, 0x04, 0x05});
  // A client abort ends the transfer without an answer; the next segment has no transfer.
  exchange({0x21, 0x01, 0x21, 0x00, 0x0E, 0, 0, 0}, {0x60, 0x01, 0x21, 0x00, 0, 0, 0, 0});
  ASSERT_TRUE(tap_->send(sdo_frame(0x605, {0x80, 0x01, 0x21, 0x00, 0x00, 0x00, 0x04, 0x05})));
  exchange({0x00, 1, 2, 3, 4, 5, 6, 7}, {0x80, 0x00, 0x00, 0x00, 0x01, 0x00, 0x04, 0x05});
  // Expedited download without size: an UNSIGNED8 takes its one byte.
  exchange({0x22, 0x01, 0x20, 0x05, 0x2A, 0xEE, 0xEE, 0xEE}, {0x60, 0x01, 0x20, 0x05, 0, 0, 0, 0});
  exchange({0x40, 0x01, 0x20, 0x05, 0, 0, 0, 0}, {0x4F, 0x01, 0x20, 0x05, 0x2A, 0, 0, 0});
  // Short frames are not SDO frames.
  exchange({0x40, 0x01, 0x20, 0x05}, {0x80, 0x01, 0x20, 0x05, 0x00, 0x00, 0x00, 0x08});
  expect_quiet(*tap_);
}

// ---- queueing, concurrency, threads, destruction -------------------------------------------------

TEST_F(Sdo, QueuedRequestsToOneNodeRunInOrderOneAtATime) {
  SdoClient& client = client_and_server();
  Recorder done;
  for (int i = 0; i < 10; ++i) {
    client.upload(kNode, 0x2001, static_cast<std::uint8_t>(i + 1), [&done, i](SdoClient::UploadResult r) {
      EXPECT_TRUE(r) << r.error().message;
      done.add(i);
    });
  }
  EXPECT_EQ(done.wait_for(10), (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));

  // On the bus: request, response, request, response, ...; each initiate names the next object.
  // Subs 4, 8 and 10 (64-bit) are segmented: three exchanges each.
  std::vector<int> initiated;
  for (int i = 0; i < 2 * (10 + 3 * 2); ++i) {
    auto f = next_frame(*tap_);
    ASSERT_TRUE(f) << "frame " << i;
    ASSERT_EQ(f->id, i % 2 == 0 ? 0x605u : 0x585u) << "frame " << i << ": two requests in flight";
    if (f->id == 0x605 && f->data[0] == 0x40) initiated.push_back(f->data[3] - 1);
  }
  EXPECT_EQ(initiated, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));
  expect_quiet(*tap_);
}

TEST_F(Sdo, TwoNodesAreServedConcurrently) {
  std::string text(200, 'x');
  for (std::uint8_t node : {std::uint8_t{5}, std::uint8_t{6}}) {
    ASSERT_TRUE(add_server(node).dictionary().set(0x2100, 0, bytes_of(text)));
  }
  SdoClient& client = make_client();
  // Both queued before the loop runs, so both start at once.
  auto a = client.upload_async(5, 0x2100, 0);
  auto b = client.upload_async(6, 0x2100, 0);
  start();
  ASSERT_TRUE(wait(a));
  ASSERT_TRUE(wait(b));

  std::vector<std::uint32_t> ids;
  for (int i = 0; i < 2 * 2 * 30; ++i) {
    auto f = next_frame(*tap_);
    ASSERT_TRUE(f);
    ids.push_back(f->id);
  }
  const auto first_606 = std::find(ids.begin(), ids.end(), 0x606u) - ids.begin();
  const auto last_585 = ids.rend() - std::find(ids.rbegin(), ids.rend(), 0x585u) - 1;
  EXPECT_LT(first_606, last_585) << "node 6 waited for node 5";
  // Per node still one at a time.
  for (std::uint32_t node : {5u, 6u}) {
    bool expect_request = true;
    for (std::uint32_t id : ids) {
      if (id != 0x600 + node && id != 0x580 + node) continue;
      EXPECT_EQ(id, expect_request ? 0x600 + node : 0x580 + node);
      expect_request = !expect_request;
    }
  }
}

// A node that never answers does not hold up another.
TEST_F(Sdo, ASilentNodeDoesNotBlockOthers) {
  SdoClient& client = client_and_server(2000ms);
  auto silent = client.upload_async(9, 0x1000, 0);
  const auto t0 = Clock::now();
  auto f = client.read_async(kNode, 0x1000, 0, DataType::unsigned32);
  auto r = wait(f);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(*r, ObjectValue{std::uint64_t{0x1A4}});
  EXPECT_LT(Clock::now() - t0, 1000ms);
  EXPECT_EQ(silent.wait_for(0ms), std::future_status::timeout);
}

TEST_F(Sdo, RequestsFromFourThreadsAtOnce) {
  add_server(5);
  add_server(6);
  SdoClient& client = make_client();
  start();
  constexpr int kThreads = 4;
  constexpr int kRounds = 25;
  std::latch go(kThreads);
  std::vector<int> failures(kThreads, 0);
  std::vector<std::jthread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      const auto node = static_cast<std::uint8_t>(5 + t % 2);
      const auto index = static_cast<std::uint16_t>(0x2200 + t);
      const auto text_index = static_cast<std::uint16_t>(0x2300 + t);
      // Write, then read back (queued behind the write): the value must be the one written.
      auto round_trip = [&](std::uint16_t idx, DataType type, const ObjectValue& v) {
        auto w = client.write_async(node, idx, 0, type, v);
        auto r = client.read_async(node, idx, 0, type);
        try {
          auto written = wait(w);
          auto read = wait(r);
          return written && read && *read == v;
        } catch (const std::exception&) {
          return false;
        }
      };
      go.arrive_and_wait();
      for (int i = 0; i < kRounds; ++i) {
        if (!round_trip(index, DataType::integer32, ObjectValue{std::int64_t{t * 100000 - i}})) {
          ++failures[static_cast<std::size_t>(t)];
        }
        const std::string s = fmt::format("thread {} round {} {}", t, i, std::string(static_cast<std::size_t>(i), '.'));
        if (i % 5 == 0 && !round_trip(text_index, DataType::visible_string, ObjectValue{s})) {
          ++failures[static_cast<std::size_t>(t)];
        }
      }
    });
  }
  threads.clear();  // joins
  EXPECT_EQ(failures, std::vector<int>(kThreads, 0));
}

TEST_F(Sdo, DestroyingTheClientCompletesEveryPendingRequest) {
  make_client(10s);
  start();
  Recorder done;
  std::vector<std::string> messages(4);
  for (int i = 0; i < 3; ++i) {
    client_->upload(9, 0x1000, static_cast<std::uint8_t>(i), [&, i](SdoClient::UploadResult r) {
      EXPECT_FALSE(r);
      EXPECT_EQ(r.error().abort_code, sdo_abort::general_error);
      messages[static_cast<std::size_t>(i)] = r.error().message;
      done.add(i);
    });
  }
  client_->download(9, 0x2000, 0, Bytes{1}, [&](SdoClient::DownloadResult r) {
    EXPECT_FALSE(r);
    messages[3] = r.error().message;
    done.add(3);
  });
  expect_traffic(*tap_, {{0x609, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}}});  // the first is in flight

  client_.reset();  // from this thread, while the loop runs
  EXPECT_EQ(done.seen(), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_TRUE(contains(messages[0], "client destroyed during the transfer")) << messages[0];
  EXPECT_TRUE(contains(messages[1], "client destroyed before the request was sent")) << messages[1];
  EXPECT_TRUE(contains(messages[3], "failed locally")) << messages[3];
  expect_traffic(*tap_, {{0x609, {0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x08}}});

  // A late answer reaches a loop whose client is gone: nothing runs.
  ASSERT_TRUE(tap_->send(sdo_frame(0x589, {0x43, 0x00, 0x10, 0x01, 1, 2, 3, 4})));
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(done.seen().size(), 4u);
}

TEST_F(Sdo, DestroyingTheClientOfALoopThatNeverRanCompletesToo) {
  make_client();
  int completed = 0;
  client_->upload(kNode, 0x1000, 0, [&](SdoClient::UploadResult r) {
    EXPECT_FALSE(r);
    ++completed;
  });
  client_->upload(0, 0x1000, 0, [&](SdoClient::UploadResult r) {
    EXPECT_FALSE(r);
    ++completed;
  });
  client_.reset();
  EXPECT_EQ(completed, 2);
  start();  // the kicks posted earlier now find a closed client
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(completed, 2);
  expect_quiet(*tap_);
}

TEST_F(Sdo, CallbacksMayQueueMoreAndMayDestroyTheClient) {
  SdoClient& client = client_and_server();
  auto last = std::make_shared<std::promise<std::string>>();
  auto result = last->get_future();
  client.upload(kNode, 0x1000, 0, [&](SdoClient::UploadResult first) {
    EXPECT_TRUE(first);
    client.read(kNode, 0x1008, 0, DataType::visible_string, [&](SdoClient::ReadResult second) {
      EXPECT_TRUE(second);
      // Destroyed from its own callback, on the loop thread: a request queued now still completes.
      client_->upload(kNode, 0x1000, 0, [last](SdoClient::UploadResult third) {
        last->set_value(third ? std::string("answered") : third.error().message);
      });
      client_.reset();
    });
  });
  EXPECT_TRUE(contains(wait(result), "client destroyed")) << "the third request";
}

TEST_F(Sdo, BlockingWrappersRefuseTheLoopThread) {
  SdoClient& client = client_and_server();
  auto p = std::make_shared<std::promise<std::string>>();
  auto f = p->get_future();
  client_loop_->post([&client, p] {
    try {
      (void)client.upload_async(kNode, 0x1000, 0);
      p->set_value("no exception");
    } catch (const std::logic_error& e) {
      p->set_value(e.what());
    }
  });
  EXPECT_TRUE(contains(wait(f), "loop thread"));
}

TEST_F(Sdo, BusSendFailureIsALocalError) {
  client_loop_->stop();
  auto bus = can::open_bus("virtual:" + name_, can::BusAccess::listen_only);
  ASSERT_TRUE(bus) << bus.error().message;
  client_loop_ = std::make_unique<BusLoop>(std::move(*bus));
  SdoClient& client = client_and_server();
  auto f = client.upload_async(kNode, 0x1000, 0);
  auto r = wait(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::general_error);
  EXPECT_TRUE(contains(r.error().message, "failed locally")) << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "bus send failed")) << r.error().message;
  expect_quiet(*tap_);
}

// CiA 301: an expedited upload answer with e = 1, s = 0 carries "an unspecified number of bytes".
// A typed read knows how many it needs: a 1- or 2-byte object so answered is read, whatever the
// other bytes hold; an untyped upload gets all four.
TEST_F(Sdo, ExpeditedUploadWithoutSizeIsReadByTheType) {
  SdoClient& client = make_client();
  start();
  const auto serve = [&](std::uint8_t sub, Bytes answer) {
    auto req = next_frame(*tap_);
    ASSERT_TRUE(req);
    ASSERT_EQ(hex(req->payload()), hex(Bytes{0x40, 0x00, 0x20, sub, 0, 0, 0, 0}));
    ASSERT_TRUE(tap_->send(sdo_frame(0x587, std::move(answer))));
  };
  auto u8 = client.read_async(7, 0x2000, 1, DataType::unsigned8);
  serve(1, {0x42, 0x00, 0x20, 0x01, 0x2A, 0xEE, 0xEE, 0xEE});
  auto r8 = wait(u8);
  ASSERT_TRUE(r8) << r8.error().message;
  EXPECT_EQ(std::get<std::uint64_t>(*r8), 0x2Au);

  auto i16 = client.read_async(7, 0x2000, 2, DataType::integer16);
  serve(2, {0x42, 0x00, 0x20, 0x02, 0x18, 0xFC, 0x00, 0x00});  // -1000
  auto r16 = wait(i16);
  ASSERT_TRUE(r16) << r16.error().message;
  EXPECT_EQ(std::get<std::int64_t>(*r16), -1000);

  auto u32 = client.read_async(7, 0x2000, 3, DataType::unsigned32);
  serve(3, {0x42, 0x00, 0x20, 0x03, 0x78, 0x56, 0x34, 0x12});
  auto r32 = wait(u32);
  ASSERT_TRUE(r32) << r32.error().message;
  EXPECT_EQ(std::get<std::uint64_t>(*r32), 0x12345678u);

  auto raw = client.upload_async(7, 0x2000, 4);
  serve(4, {0x42, 0x00, 0x20, 0x04, 0x01, 0x02, 0x03, 0x04});
  auto rr = wait(raw);
  ASSERT_TRUE(rr) << rr.error().message;
  EXPECT_EQ(hex(*rr), "01 02 03 04");
  expect_quiet(*tap_);  // no abort anywhere
}

// An SDO frame is always 8 bytes (CiA 301). A shorter frame on 580h + n is not the server's answer:
// it is ignored and the transfer goes on with the real answer.
TEST_F(Sdo, ShortFrameOnTheResponseIdentifierIsIgnored) {
  SdoClient& client = make_client();
  start();
  auto f = client.upload_async(7, 0x2000, 0);
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x4B, 0x00, 0x20, 0x00})));
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x4B, 0x00, 0x20, 0x00, 0x11, 0x22, 0, 0})));
  auto r = wait(f);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(hex(*r), "11 22");
  expect_quiet(*tap_);  // the client sent no abort
}

// Service calls are limited per device: a request that finds the limit waiting is refused at once
// (abort code 0: nothing went on the bus), and cancel_waiting answers the waiting ones at once.
// The bridge's own requests (boot, polls) are never limited nor cancelled.
TEST_F(Sdo, LimitedRequestsAreRefusedAtTheLimitAndCancelledOnDemand) {
  SdoClient& client = make_client(2000ms);
  start();
  Recorder done;
  std::mutex m;
  std::vector<SdoClient::UploadResult> results(6, SdoClient::UploadResult(SdoError{}));
  const auto limited = [&](int i) {
    client.upload(
        9, 0x2000, static_cast<std::uint8_t>(i),
        [&, i](SdoClient::UploadResult r) {
          {
            std::lock_guard lock(m);
            results[static_cast<std::size_t>(i)] = std::move(r);
          }
          done.add(i);
        },
        SdoClient::Limit{2});
  };
  limited(0);  // in flight at node 9, which never answers
  ASSERT_TRUE(next_frame(*tap_));
  limited(1);                                    // waits
  auto own = client.upload_async(9, 0x2000, 9);  // the bridge's own: not counted, not cancelled
  limited(2);                                    // waits: the limit is reached
  limited(3);                                    // refused at once
  auto seen = done.wait_for(1, 500ms);
  ASSERT_EQ(seen, std::vector<int>{3});
  {
    std::lock_guard lock(m);
    ASSERT_FALSE(results[3]);
    EXPECT_EQ(results[3].error().abort_code, 0u);
    EXPECT_TRUE(contains(results[3].error().message, "2 requests already wait for this device (limit 2)"))
        << results[3].error().message;
  }
  client.cancel_waiting(9, "node 9 went offline");
  seen = done.wait_for(3, 500ms);
  ASSERT_EQ(seen.size(), 3u) << "the waiting requests were not answered at once";
  {
    std::lock_guard lock(m);
    for (int i : {1, 2}) {
      ASSERT_FALSE(results[static_cast<std::size_t>(i)]);
      EXPECT_EQ(results[static_cast<std::size_t>(i)].error().abort_code, 0u);
      EXPECT_TRUE(contains(results[static_cast<std::size_t>(i)].error().message, "not sent: node 9 went offline"));
    }
  }
  // The one in flight and the bridge's own request time out as before.
  auto r0 = done.wait_for(4, 4000ms);
  ASSERT_EQ(r0.size(), 4u);
  EXPECT_EQ(r0.back(), 0);
  auto ro = wait(own, 5000ms);
  ASSERT_FALSE(ro);
  EXPECT_EQ(ro.error().abort_code, sdo_abort::timed_out);
}

// An upload is bounded (SdoClient::kDefaultMaxUpload): a server indicating more is aborted with
// 05040005h (out of memory) before a segment is asked for, so no device decides what the loop
// thread allocates.
TEST_F(Sdo, AnUploadIndicatingMoreThanTheLimitIsAbortedAtOnce) {
  SdoClient& client = make_client();
  start();
  auto f = client.upload_async(7, 0x2000, 0);
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}}});
  const auto size = static_cast<std::uint32_t>(SdoClient::kDefaultMaxUpload + 1);
  ASSERT_TRUE(tap_->send(
      sdo_frame(0x587, {0x41, 0x00, 0x20, 0x00, static_cast<std::uint8_t>(size), static_cast<std::uint8_t>(size >> 8),
                        static_cast<std::uint8_t>(size >> 16), static_cast<std::uint8_t>(size >> 24)})));
  expect_traffic(*tap_, {{0x607, {0x80, 0x00, 0x20, 0x00, 0x05, 0x00, 0x04, 0x05}}});
  auto r = wait(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::out_of_memory);
  EXPECT_TRUE(contains(r.error().message, "aborted by the client")) << r.error().message;
  expect_quiet(*tap_);
}

// A server that indicates no size and never sends its last segment is stopped at the limit too:
// the client asks for segments until the data would pass kDefaultMaxUpload, then aborts.
TEST_F(Sdo, AnUploadWithoutSizeIsAbortedAtTheLimit) {
  SdoClient& client = make_client();
  start();
  auto f = client.upload_async(7, 0x2000, 0);
  expect_traffic(*tap_, {{0x607, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}}});
  ASSERT_TRUE(tap_->send(sdo_frame(0x587, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0})));  // segmented, no size
  constexpr std::size_t kSegments = SdoClient::kDefaultMaxUpload / 7 + 1;           // the first past the limit
  std::size_t segments = 0;
  std::optional<CanFrame> last;
  for (bool toggle = false; segments <= kSegments; toggle = !toggle) {
    last = next_frame(*tap_);
    ASSERT_TRUE(last) << "no request after " << segments << " segments";
    if (last->data[0] != (toggle ? 0x70 : 0x60)) break;  // not a segment request: the client stopped
    const auto t = static_cast<std::uint8_t>(toggle ? 0x10 : 0x00);
    ASSERT_TRUE(tap_->send(sdo_frame(0x587, {t, 1, 2, 3, 4, 5, 6, 7})));  // 7 bytes, never the last
    ++segments;
  }
  EXPECT_EQ(segments, kSegments) << "the client stopped asking elsewhere than at the limit";
  ASSERT_TRUE(last);
  EXPECT_EQ(fmt::format("{:03X} {}", last->id, hex(last->payload())), "607 80 00 20 00 05 00 04 05");
  auto r = wait(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().abort_code, sdo_abort::out_of_memory);
}

}  // namespace
}  // namespace lb::canopen
