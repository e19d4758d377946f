// linebridge-sim as a CiA 301 device, seen by a peer master: the real simulator process on a
// virtual bus, and this test as the master (its own bus loop, SDO client, SYNC and NMT frames, and
// a recorder of every frame with the time it arrived). No bridge and no DDS.
//
// Every expected value is written here by hand from CiA 301 (../shared/design/cia301-essentials.md)
// and the profiles' spec tables (../shared/specs: saw 3.1 tables 2-13, corrugator 3.1 tables
// 2-13, feeder 1.1 sections 4.2-4.6, puller 1.0 section 2), or from the line file below.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/sdo_client.hpp"
#include "support/child_process.hpp"

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using lb::can::CanFrame;

namespace {

// The line the simulator plays. Node-IDs are this test's choice.
constexpr std::uint8_t kSaw = 5, kFeeder = 6, kCorrugator = 7, kPuller = 8, kSaw2 = 9, kPullerRw = 10;
constexpr std::uint32_t kSaw2DeviceType = 0x000201A4, kSaw2Vendor = 0x0000ABCD, kSaw2Product = 0x00001234,
                        kSaw2Revision = 0x00020003, kSaw2Serial = 0x00C0FFEE;

// CiA 301 abort codes.
constexpr std::uint32_t kTimeout = 0x05040000, kReadOnly = 0x06010002, kNoObject = 0x06020000, kCannotMap = 0x06040041,
                        kLengthExceeded = 0x06040042, kNoSub = 0x06090011, kRange = 0x06090030,
                        kDeviceState = 0x08000022;

// NMT commands (CiA 301).
constexpr std::uint8_t kStart = 0x01, kStop = 0x02, kPreOperational = 0x80, kResetNode = 0x81,
                       kResetCommunication = 0x82;

// A puller whose COB-IDs are CiA 301's rw (the 1.0 text makes them ro): the plain CiA 301 device,
// whose PDOs a master can make invalid and remap. Its profile file is the puller 1.0 one with that
// one change, as version 9.1.
std::string puller_rw_profile() {
  std::ifstream in(std::string(LB_SOURCE_DIR) + "/config/profiles/cia420-2-puller-1.0.yaml");
  std::stringstream text;
  text << in.rdbuf();
  auto s = text.str();
  const auto replace_all = [&s](const std::string& from, const std::string& to) {
    for (auto pos = s.find(from); pos != std::string::npos; pos = s.find(from, pos + to.size()))
      s.replace(pos, from.size(), to);
  };
  replace_all("version: \"1.0\"", "version: \"9.1\"");
  replace_all("access: {cob_id: ro, transmission_type: rw}", "access: {cob_id: rw, transmission_type: rw}");
  return s;
}

std::string line_config(const std::string& bus, const std::string& profiles_dir) {
  return "line: conformance\n"
         "profiles_dir: '" +
         profiles_dir +
         "'\n"
         "buses:\n"
         "  - {name: c, interface: '" +
         bus +
         "'}\n"
         "devices:\n"
         // The bridge's keys (pdos, configure, identity) must not reach the simulated device.
         "  - name: saw\n"
         "    bus: c\n"
         "    node_id: 5\n"
         "    profile: cia420-4\n"
         "    version: '3.1'\n"
         "    pdos: {tpdo1: {transmission_type: 4}}\n"
         "    configure: [{object: saw_sync_speed_set_maximum, value: 45000}]\n"
         "    identity: {vendor_id: 0x11111111}\n"
         "    simulation: {heartbeat_period_ms: 100}\n"
         "  - {name: feeder, bus: c, node_id: 6, profile: cia414-2, version: '1.1', simulation: {heartbeat_period_ms: "
         "100}}\n"
         "  - {name: corrugator, bus: c, node_id: 7, profile: cia420-3, version: '3.1'}\n"
         "  - {name: puller, bus: c, node_id: 8, profile: cia420-2, version: '1.0'}\n"
         "  - name: saw2\n"
         "    bus: c\n"
         "    node_id: 9\n"
         "    profile: cia420-4\n"
         "    version: '3.1'\n"
         "    pdos: {tpdo2: {transmission_type: 7}}\n"
         "    simulation:\n"
         "      heartbeat_period_ms: 0\n"
         "      identity: {device_type: 0x000201A4, vendor_id: 0x0000ABCD, product_code: 0x00001234, revision: "
         "0x00020003,"
         " serial_number: 0x00C0FFEE}\n"
         "      pdos: {tpdo2: {transmission_type: 3, mapping: [0x60070020, 0x60010020]}}\n"
         "      ignore_writes: [{index: 0x6006}, {index: 0x1801, sub: 2}]\n"
         "  - {name: puller_rw, bus: c, node_id: 10, profile: cia420-2, version: '9.1'}\n";
}

struct Seen {
  Clock::time_point at;
  CanFrame frame;
  bool ours = false;  // sent by this test (SYNC, NMT, RPDOs)
};

using Entries = std::vector<std::uint64_t>;

struct Sdo {
  bool ok = false;
  std::uint64_t value = 0;
  std::uint32_t abort = 0;
  std::string message;
};

std::string hex(std::uint64_t v) {
  std::ostringstream s;
  s << std::hex << std::uppercase << v << "h";
  return s.str();
}

// The test's side of the bus: a CANopen master with a frame recorder. The recorder runs on the
// loop thread, so frames this test sends and frames it receives are in one order.
class PeerMaster {
 public:
  explicit PeerMaster(const std::string& uri) : loop_(lb::can::open_bus(uri).value()), sdo_(loop_, 300ms) {
    for (std::uint32_t id = 0; id < 0x800; ++id) loop_.on_frame(id, [this](const CanFrame& f) { record(f, false); });
    loop_.on_other_frame([this](const CanFrame& f) {
      if (f.extended && !f.error) record(f, false);
    });
    sync_timer_ = loop_.create_timer([this] { transmit(lb::can::make_frame(0x080, {})); });
    loop_.start();
  }
  ~PeerMaster() { loop_.stop(); }

  void send(const CanFrame& f) {
    std::promise<void> done;
    loop_.post([&] {
      transmit(f);
      done.set_value();
    });
    done.get_future().wait();
  }
  void nmt(std::uint8_t command, std::uint8_t node) { send(lb::can::make_frame(0x000, {command, node})); }
  void sync() { send(lb::can::make_frame(0x080, {})); }
  // n SYNCs, `gap` apart.
  void syncs(int n, std::chrono::milliseconds gap) {
    for (int i = 0; i < n; ++i) {
      sync();
      std::this_thread::sleep_for(gap);
    }
  }
  void sync_every(std::chrono::milliseconds period) {
    loop_.post([this, period] { loop_.arm_timer(sync_timer_, period, period); });
  }
  void stop_sync() {
    std::promise<void> done;
    loop_.post([&] {
      loop_.disarm_timer(sync_timer_);
      done.set_value();
    });
    done.get_future().wait();
  }

  Sdo read(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
    auto r = sdo_.upload_async(node, index, sub).get();
    Sdo out;
    if (!r) return {false, 0, r.error().abort_code, r.error().message};
    out.ok = true;
    for (std::size_t i = 0; i < r->size() && i < 8; ++i) out.value |= std::uint64_t{(*r)[i]} << (8 * i);
    return out;
  }
  Sdo write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint64_t value, std::size_t size) {
    std::vector<std::uint8_t> bytes(size);
    for (std::size_t i = 0; i < size; ++i) bytes[i] = static_cast<std::uint8_t>(value >> (8 * i));
    auto r = sdo_.download_async(node, index, sub, std::move(bytes)).get();
    if (!r) return {false, 0, r.error().abort_code, r.error().message};
    return {true, 0, 0, ""};
  }
  std::uint32_t write_abort(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint64_t value,
                            std::size_t size) {
    return write(node, index, sub, value, size).abort;
  }

  std::vector<Seen> frames() {
    std::lock_guard lock(m_);
    return seen_;
  }
  void clear() {
    std::lock_guard lock(m_);
    seen_.clear();
  }
  // Frames with this identifier (and frame format) others sent, since the last clear().
  std::vector<Seen> from(std::uint32_t id, bool extended = false) {
    std::vector<Seen> out;
    for (const auto& s : frames()) {
      if (!s.ours && s.frame.id == id && s.frame.extended == extended) out.push_back(s);
    }
    return out;
  }
  bool wait_for(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
    const auto end = Clock::now() + timeout;
    while (Clock::now() < end) {
      if (done()) return true;
      std::this_thread::sleep_for(10ms);
    }
    return done();
  }
  bool wait_frame(std::uint32_t id, const std::function<bool(const CanFrame&)>& match,
                  std::chrono::milliseconds timeout) {
    return wait_for(
        [&] {
          for (const auto& s : from(id)) {
            if (match(s.frame)) return true;
          }
          return false;
        },
        timeout);
  }

 private:
  void record(const CanFrame& f, bool ours) {
    std::lock_guard lock(m_);
    seen_.push_back({Clock::now(), f, ours});
  }
  void transmit(const CanFrame& f) {
    record(f, true);
    (void)loop_.send(f);
  }

  std::mutex m_;
  std::vector<Seen> seen_;
  lb::canopen::BusLoop loop_;
  lb::canopen::SdoClient sdo_;
  lb::canopen::BusLoop::TimerId sync_timer_{};
};

bool is_boot_up(const CanFrame& f) { return f.len == 1 && f.data[0] == 0x00; }

std::vector<std::uint8_t> bytes(const CanFrame& f) { return {f.data.begin(), f.data.begin() + f.len}; }

// Gaps between consecutive frames, in ms.
std::vector<double> gaps_ms(const std::vector<Seen>& frames) {
  std::vector<double> out;
  for (std::size_t i = 1; i < frames.size(); ++i) {
    out.push_back(std::chrono::duration<double, std::milli>(frames[i].at - frames[i - 1].at).count());
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

class SimConformance : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    tag_ = std::to_string(::getpid()) + "-" + info->name();
    bus_ = "virtual:conf-" + tag_;
    bus_.resize(std::min<std::size_t>(bus_.size(), 90));
    config_ = ::testing::TempDir() + "/conformance_" + tag_ + ".yaml";
    const auto profiles = ::testing::TempDir() + "/conformance_profiles_" + tag_;
    std::filesystem::create_directories(profiles);
    std::ofstream(profiles + "/cia420-2-puller-9.1.yaml") << puller_rw_profile();
    std::ofstream(config_) << line_config(bus_, profiles);
    master_ = std::make_unique<PeerMaster>(bus_);  // first member: the hub lives in this process
  }
  void TearDown() override {
    if (sim_) sim_->stop();
    master_.reset();
  }

  // The simulator playing these devices (by name in the line file); returns when each sent its boot-up.
  void start_sim(const std::vector<std::pair<std::string, std::uint8_t>>& devices) {
    std::vector<std::string> argv{LB_BIN_SIM, "--config", config_};
    for (const auto& [name, node] : devices) {
      argv.push_back("--device");
      argv.push_back(name);
    }
    sim_ = std::make_unique<lb::test::ChildProcess>(argv, ::testing::TempDir() + "/conformance_sim_" + tag_ + ".log");
    ASSERT_TRUE(sim_->started());
    for (const auto& [name, node] : devices) {
      ASSERT_TRUE(master_->wait_frame(0x700U + node, is_boot_up, 10s)) << name << " sent no boot-up\n" << log();
    }
  }
  std::string log() const { return "--- sim log ---\n" + (sim_ ? sim_->log() : std::string()); }

  // An SDO read that must succeed.
  std::uint64_t read(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
    const auto r = master_->read(node, index, sub);
    EXPECT_TRUE(r.ok) << "read " << hex(index) << " sub " << int(sub) << ": " << r.message;
    return r.value;
  }
  // A PDO mapping parameter as a master reads it: sub 0 = n, then the entries 1..n.
  std::vector<std::uint64_t> mapping(std::uint8_t node, std::uint16_t index) {
    std::vector<std::uint64_t> entries;
    const auto count = read(node, index, 0);
    for (std::uint64_t sub = 1; sub <= count && sub <= 64; ++sub)
      entries.push_back(read(node, index, static_cast<std::uint8_t>(sub)));
    return entries;
  }
  void write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint64_t value, std::size_t size) {
    const auto r = master_->write(node, index, sub, value, size);
    EXPECT_TRUE(r.ok) << "write " << hex(index) << " sub " << int(sub) << " = " << hex(value) << ": " << r.message;
  }

  std::string tag_, bus_, config_;
  std::unique_ptr<PeerMaster> master_;
  std::unique_ptr<lb::test::ChildProcess> sim_;
};

}  // namespace

// Saw 3.1 tables 2-13, feeder 1.1 4.2-4.6: the PDO objects a master finds, and what it may not write.
TEST_F(SimConformance, PdoObjectsAndWhatTheProfileKeepsConstant) {
  start_sim({{"saw", kSaw}, {"feeder", kFeeder}});
  // Saw 3.1, pre-operational after boot-up. 1800h: COB-ID const 4000 0180h + node-ID.
  const auto highest = read(kSaw, 0x1800, 0);
  EXPECT_TRUE(highest >= 2 && highest <= 6) << highest;
  EXPECT_EQ(read(kSaw, 0x1800, 1), 0x40000185u);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1800, 1, 0x40000185, 4), kReadOnly);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1800, 1, 0xC0000185, 4), kReadOnly);
  // The line file's transmission type 4 for TPDO1 is the bridge's business: the device has 01h.
  EXPECT_EQ(read(kSaw, 0x1800, 2), 1u);
  EXPECT_EQ(read(kSaw, 0x1801, 1), 0x40000285u);
  EXPECT_EQ(read(kSaw, 0x1400, 1), 0x40000205u);
  // 1A00h: sub 0 02h, subs 1-2 const 6030 00 10h, 6000 00 20h, sub 3 mandatory, const, a 16-bit
  // manufacturer-specific object (the unused bytes: a second status word).
  EXPECT_EQ(mapping(kSaw, 0x1A00), (Entries{0x60300010, 0x60000020}));
  const auto third = master_->read(kSaw, 0x1A00, 3);
  ASSERT_TRUE(third.ok) << "1A00h sub 3 is mandatory: " << third.message;
  EXPECT_EQ(third.value & 0xFF, 0x10u) << hex(third.value);
  EXPECT_GE(third.value >> 16, 0x2000u) << "a manufacturer-specific object: " << hex(third.value);
  EXPECT_LT(third.value >> 16, 0x6000u) << "a manufacturer-specific object: " << hex(third.value);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A00, 1, 0x60300010, 4), kReadOnly);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A00, 3, third.value, 4), kReadOnly);
  // 1A01h: sub 0 const 02h, subs 1-2 const 6001 00 20h, 6007 00 20h.
  EXPECT_EQ(mapping(kSaw, 0x1A01), (Entries{0x60010020, 0x60070020}));
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A01, 0, 2, 1), kReadOnly);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A01, 1, 0x60070020, 4), kReadOnly);
  // 1600h: sub 0 const 03h, subs 1-3 const 6020 00 10h, 6005 00 10h, 6002 00 20h.
  EXPECT_EQ(mapping(kSaw, 0x1600), (Entries{0x60200010, 0x60050010, 0x60020020}));
  EXPECT_EQ(master_->write_abort(kSaw, 0x1600, 2, 0x60050010, 4), kReadOnly);

  // 1A00h sub 0: "rw (constant in NMT operational state)", value range 00h, 02h to 03h.
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A00, 0, 1, 1), kRange);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A00, 0, 4, 1), kRange);
  write(kSaw, 0x1A00, 0, 3, 1);
  EXPECT_EQ(read(kSaw, 0x1A00, 0), 3u);
  write(kSaw, 0x1A00, 0, 0, 1);
  write(kSaw, 0x1A00, 0, 2, 1);
  master_->nmt(kStart, kSaw);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A00, 0, 3, 1), kDeviceState);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1A00, 0, 2, 1), kDeviceState);
  EXPECT_EQ(read(kSaw, 0x1A00, 0), 2u);

  // Transmission types (CiA 301): 241..251 reserved; 252/253 only for TPDOs.
  EXPECT_EQ(master_->write_abort(kSaw, 0x1801, 2, 245, 1), kRange);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1400, 2, 252, 1), kRange);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1400, 2, 241, 1), kRange);
  write(kSaw, 0x1801, 2, 252, 1);
  write(kSaw, 0x1400, 2, 254, 1);
  EXPECT_EQ(read(kSaw, 0x1801, 2), 252u);

  // Feeder 1.1: 1400h sub 0 ro 02h (no inhibit time, no event timer), mapping constant.
  EXPECT_EQ(read(kFeeder, 0x1400, 0), 2u);
  EXPECT_EQ(master_->read(kFeeder, 0x1400, 3).abort, kNoSub);
  EXPECT_EQ(master_->read(kFeeder, 0x1400, 5).abort, kNoSub);
  EXPECT_EQ(read(kFeeder, 0x1400, 1), 0x40000206u);
  EXPECT_EQ(read(kFeeder, 0x1400, 2), 255u);
  EXPECT_EQ(mapping(kFeeder, 0x1600), (Entries{0x600C0108, 0x600C0208, 0x600C0308, 0x600C0408, 0x600C0508}));
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1600, 0, 0, 1), kReadOnly);
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1600, 1, 0x600C0108, 4), kReadOnly);
  EXPECT_EQ(mapping(kFeeder, 0x1A00), (Entries{0x60100020}));
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1A00, 0, 0, 1), kReadOnly);
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1A00, 1, 0x60100020, 4), kReadOnly);
  const auto feeder_tpdo = read(kFeeder, 0x1800, 1);
  EXPECT_TRUE(feeder_tpdo == 0x40000186u || feeder_tpdo == 0xC0000186u) << hex(feeder_tpdo);

  // Feeder TPDO1 COB-ID rw (CiA 301 rules): a valid PDO keeps its identifier.
  write(kFeeder, 0x1800, 1, 0x40000186, 4);
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1800, 1, 0x40000190, 4), kRange);
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1800, 1, 0x60000186, 4), kRange) << "bit 29 of a valid PDO";
  write(kFeeder, 0x1800, 1, 0xC0000186, 4);
  write(kFeeder, 0x1800, 1, 0xC0000190, 4);  // not valid: any identifier
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1800, 1, 0x40000150, 4), kRange) << "101h-180h are restricted";
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1800, 1, 0x40000605, 4), kRange) << "601h-67Fh are restricted";
  EXPECT_EQ(master_->write_abort(kFeeder, 0x1800, 1, 0x40000800, 4), kRange) << "an 11-bit identifier above 7FFh";
  write(kFeeder, 0x1800, 1, 0x40000190, 4);
  EXPECT_EQ(read(kFeeder, 0x1800, 1), 0x40000190u);
}

// CiA 301: 1..240 = after every n-th SYNC; 252 = on remote request only, never by itself.
TEST_F(SimConformance, SynchronousTransmissionTypesCountSyncs) {
  start_sim({{"saw", kSaw}});
  write(kSaw, 0x1801, 2, 2, 1);  // TPDO2 after every 2nd SYNC
  master_->nmt(kStart, kSaw);
  // Started (its heartbeat says operational) before the first SYNC it is to count.
  ASSERT_TRUE(master_->wait_frame(
      0x705, [](const CanFrame& f) { return f.len == 1 && f.data[0] == 0x05; }, 10s))
      << log();
  master_->clear();
  // SYNC by SYNC, each after the device answered the one before (a loaded machine delays frames;
  // a fixed period would let an answer be counted after the next SYNC).
  for (std::size_t k = 1; k <= 20; ++k) {
    master_->syncs(1, 0ms);
    ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x185).size() >= k; }, 10s))
        << "no TPDO1 after SYNC " << k;
  }
  ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x285).size() >= 10; }, 10s));
  // Which SYNC (1..20) each TPDO went out after, in the one order the recorder saw. The device
  // sends TPDO2 after TPDO1 on the same SYNC, so a TPDO2 follows as many TPDO1s as SYNCs it counted.
  int syncs = 0;
  int tpdo1_seen = 0;
  std::vector<int> tpdo1, tpdo2;
  for (const auto& s : master_->frames()) {
    if (s.ours && s.frame.id == 0x080) ++syncs;
    if (!s.ours && s.frame.id == 0x185) tpdo1.push_back(syncs), ++tpdo1_seen;
    if (!s.ours && s.frame.id == 0x285) tpdo2.push_back(tpdo1_seen);
  }
  EXPECT_EQ(syncs, 20);
  std::vector<int> every(20), even;
  for (int k = 1; k <= 20; ++k) every[k - 1] = k;
  for (int k = 2; k <= 20; k += 2) even.push_back(k);
  EXPECT_EQ(tpdo1, every) << "TPDO1, type 1: after every SYNC";
  EXPECT_EQ(tpdo2, even) << "TPDO2, type 2: after every 2nd SYNC";
  for (const auto& f : master_->from(0x285)) EXPECT_EQ(f.frame.len, 8);  // 6001h + 6007h, 32 bits each

  // 252: synchronous RTR only; never sent spontaneously.
  write(kSaw, 0x1801, 2, 252, 1);
  master_->clear();
  master_->syncs(10, 20ms);
  // TPDO2 would follow TPDO1 on the same SYNC: once the 10th TPDO1 is here, so would be a TPDO2.
  ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x185).size() >= 10; }, 10s));
  EXPECT_TRUE(master_->from(0x285).empty());
  EXPECT_EQ(master_->from(0x185).size(), 10u);
}

// CiA 301 1005h COB-ID SYNC is rw: a master may move SYNC to another identifier. The saw then takes
// only that identifier as SYNC (its synchronous TPDO1 follows it, not 080h), refuses to produce
// SYNC (bit 30) or a 29-bit identifier (bit 29) with 0609 0030h, and a reset communication puts
// 080h back. (The simulator refused every write to 1005h before.)
TEST_F(SimConformance, CobIdSyncIsWritable) {
  start_sim({{"saw", kSaw}});
  master_->nmt(kStart, kSaw);
  EXPECT_EQ(master_->read(kSaw, 0x1005, 0).value, 0x80u);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1005, 0, 0x4000'0080, 4), 0x0609'0030u) << "this device cannot produce SYNC";
  EXPECT_EQ(master_->write_abort(kSaw, 0x1005, 0, 0x2000'0080, 4), 0x0609'0030u) << "no 29-bit SYNC here";
  ASSERT_TRUE(master_->write(kSaw, 0x1005, 0, 0x81, 4).ok);
  EXPECT_EQ(master_->read(kSaw, 0x1005, 0).value, 0x81u);
  master_->clear();
  // Both paced 20 ms apart, as a master would send them (a stream, not a wait): what counts is
  // the order of frames below, not the time.
  master_->syncs(5, 20ms);  // on 080h: no longer SYNC for the saw
  for (int i = 0; i < 5; ++i) {
    master_->send(lb::can::make_frame(0x081, {}));
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(master_->wait_for([&] { return master_->from(0x185).size() >= 5; }, 2s));
  // Every TPDO1 came after a SYNC on 081h, none after one on 080h: count them in order.
  int after_080 = 0, after_081 = 0, last = 0;
  for (const auto& s : master_->frames()) {
    if (s.ours && s.frame.id == 0x080) last = 0x080;
    if (s.ours && s.frame.id == 0x081) last = 0x081;
    if (!s.ours && s.frame.id == 0x185) (last == 0x081 ? after_081 : after_080) += 1;
  }
  EXPECT_EQ(after_080, 0);
  EXPECT_EQ(after_081, 5);
  master_->nmt(kResetCommunication, kSaw);
  EXPECT_TRUE(master_->wait_for([&] { return master_->read(kSaw, 0x1005, 0).value == 0x80u; }, 2s));
}

// CiA 301: 254/255 = on an event, never sooner than the inhibit time after the previous frame,
// and again when the event timer expires. Corrugator 3.1 TPDO1 (table 3: only the COB-ID's valid
// bit is writable; the inhibit time is written while the PDO is not valid, CiA 301), 1A00h sub 0
// = 4 (table 5): the 16-bit manufacturer-specific object rides in the unused bytes (8 bytes in
// all), and it changes.
TEST_F(SimConformance, EventDrivenTpdoObeysInhibitTimeAndEventTimer) {
  start_sim({{"corrugator", kCorrugator}});
  write(kCorrugator, 0x1800, 1, 0xC0000187, 4);  // not valid
  write(kCorrugator, 0x1A00, 0, 4, 1);
  write(kCorrugator, 0x1800, 2, 254, 1);
  write(kCorrugator, 0x1800, 3, 500, 2);         // 50 ms
  write(kCorrugator, 0x1800, 5, 300, 2);         // 300 ms
  write(kCorrugator, 0x1800, 1, 0x40000187, 4);  // valid again
  master_->nmt(kStart, kCorrugator);
  master_->clear();
  master_->sync_every(10ms);  // the manufacturer word changes at every SYNC: events come faster than allowed
  // Twenty TPDOs waited for (at most one per 50 ms: a second or more), then the SYNCs stop.
  const bool enough = master_->wait_for([&] { return master_->from(0x187).size() >= 20; }, 20s);
  master_->stop_sync();
  ASSERT_TRUE(enough) << log();
  const auto busy = master_->from(0x187);
  for (const auto& s : busy) EXPECT_EQ(s.frame.len, 8) << "6030h, 6000h, 6006h (16 each) + the manufacturer word (16)";
  // Gaps are measured where the frames arrive: on a loaded machine a late delivery shortens the
  // next gap, so single gaps prove little. Without the inhibit time the frames would come every
  // 10 ms (one per SYNC, median gap 10 ms); with it at most one per 50 ms over the span they
  // cover (first to last arrival; two more for a late first and an early last delivery).
  const auto span_ms = std::chrono::duration_cast<std::chrono::milliseconds>(busy.back().at - busy.front().at).count();
  EXPECT_LE(busy.size(), static_cast<std::size_t>(span_ms / 50) + 2u)
      << "inhibit time 50 ms: " << busy.size() << " frames in " << span_ms << " ms";
  EXPECT_GE(median(gaps_ms(busy)), 45.0) << "inhibit time 50 ms";
  for (const double gap : gaps_ms(busy)) EXPECT_LE(gap, 300.0 + 100.0) << "event timer 300 ms";
  EXPECT_NE(bytes(busy.front().frame), bytes(busy.back().frame));
  std::set<std::vector<std::uint8_t>> tails;
  for (const auto& s : busy) tails.insert({s.frame.data.begin() + 6, s.frame.data.begin() + 8});
  EXPECT_GT(tails.size(), busy.size() / 2) << "the manufacturer word changes";

  // No more SYNC, nothing changes: only the event timer sends. Six frames waited for (a loaded
  // machine delays them); the median of their gaps is the event timer's period (a frame sent on
  // every change or SYNC would shorten it, a stopped timer would leave fewer than six). The pause
  // lets the last SYNC's event (inhibited up to 50 ms) pass before the count starts; a stray one
  // would still be a single short gap, which the median does not follow.
  std::this_thread::sleep_for(100ms);
  master_->clear();
  ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x187).size() >= 6; }, 15s)) << log();
  const auto quiet = master_->from(0x187);
  EXPECT_GE(median(gaps_ms(quiet)), 270.0) << "event timer 300 ms";
  EXPECT_LE(median(gaps_ms(quiet)), 360.0) << "event timer 300 ms";
}

// COB-ID bit 31 (not valid: neither sent nor taken), bit 29 (29-bit identifier, extended frames).
TEST_F(SimConformance, ValidBitAndExtendedIdentifiers) {
  start_sim({{"corrugator", kCorrugator}, {"feeder", kFeeder}});
  // Corrugator 3.1 table 3: TPDO1 COB-ID rw, 4000 0180h or C000 0180h + node-ID: only bit 31 changes.
  EXPECT_EQ(read(kCorrugator, 0x1800, 1), 0x40000187u);
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1800, 1, 0x40000190, 4), kRange);
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1800, 1, 0xC0000190, 4), kRange);
  // Table 5: 1A00h sub 0 00h, 03h to 04h; sub 4 optional, a manufacturer-specific object.
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1A00, 0, 2, 1), kRange);
  EXPECT_EQ(mapping(kCorrugator, 0x1A00), (Entries{0x60300010, 0x60000010, 0x60060010}));
  const auto fourth = read(kCorrugator, 0x1A00, 4);
  EXPECT_EQ(fourth & 0xFF, 0x10u) << "16 bits fill the frame: " << hex(fourth);
  // Table 13: 1600h sub 0 00h, 02h to 03h; sub 3 optional, manufacturer-specific.
  EXPECT_EQ(mapping(kCorrugator, 0x1600), (Entries{0x60200010, 0x60020010}));
  const auto third = read(kCorrugator, 0x1600, 3);
  EXPECT_EQ(third & 0xFF, 0x10u) << "a second control word: " << hex(third);
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1600, 0, 1, 1), kRange);
  write(kCorrugator, 0x1600, 0, 3, 1);
  write(kCorrugator, 0x1600, 0, 2, 1);
  master_->nmt(kStart, kCorrugator);
  // One TPDO1 and one TPDO2 per SYNC (transmission type 1), each waited for: the SYNCs'
  // answers arrive late on a loaded machine, they do not go missing.
  const auto answered = [this](std::uint32_t id, std::size_t n) {
    return master_->wait_for([&] { return master_->from(id).size() >= n; }, 10s);
  };
  master_->clear();
  master_->syncs(10, 20ms);
  EXPECT_TRUE(answered(0x187, 10)) << log();
  EXPECT_TRUE(answered(0x287, 10)) << log();
  EXPECT_EQ(master_->from(0x187).size(), 10u);
  EXPECT_EQ(master_->from(0x287).size(), 10u);
  write(kCorrugator, 0x1800, 1, 0xC0000187, 4);  // while operational: only the valid bit
  master_->clear();
  master_->syncs(10, 20ms);
  EXPECT_TRUE(answered(0x287, 10)) << log();  // every SYNC answered by TPDO2: TPDO1 would have been by now
  EXPECT_TRUE(master_->from(0x187).empty()) << "TPDO1 not valid";
  EXPECT_EQ(master_->from(0x287).size(), 10u);
  write(kCorrugator, 0x1800, 1, 0x40000187, 4);
  master_->clear();
  master_->syncs(5, 20ms);
  EXPECT_TRUE(answered(0x187, 5)) << log();
  EXPECT_TRUE(answered(0x287, 5)) << log();
  EXPECT_EQ(master_->from(0x187).size(), 5u);

  // Feeder TPDO1 to a 29-bit identifier, the CiA 301 way: not valid first, then valid with bit 29.
  write(kFeeder, 0x1800, 1, 0xC0000186, 4);
  write(kFeeder, 0x1800, 1, 0x21ABCDE6, 4);
  EXPECT_EQ(read(kFeeder, 0x1800, 1), 0x21ABCDE6u);
  master_->nmt(kStart, kFeeder);
  master_->clear();
  // RPDO2 (300h + node-ID): loom status 600Ah = 1 (start advice), 6004h = 0: the loom runs and
  // the feeder sends an unwinding time (6010h) for every winding.
  master_->send(lb::can::make_frame(0x306, {0x01, 0x00, 0x00, 0x00, 0x00}));
  ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x01ABCDE6, true).size() >= 3; }, 3s)) << log();
  for (const auto& s : master_->from(0x01ABCDE6, true)) {
    EXPECT_EQ(s.frame.len, 4);
    EXPECT_NE(s.frame.data[2], 0) << "6010h bits 16..23: winding number 1 to 50 (4.6: one TPDO per winding)";
  }
  EXPECT_TRUE(master_->from(0x186).empty());
  // Not valid: nothing at all. The write is confirmed once it took effect; a TPDO already queued
  // then may still arrive, so the count starts at the feeder's next heartbeat (706h, every 100 ms),
  // and six more heartbeats (half a second) are the marker for the negative check.
  write(kFeeder, 0x1800, 1, 0xA1ABCDE6, 4);
  master_->clear();
  ASSERT_TRUE(master_->wait_for([&] { return !master_->from(0x706).empty(); }, 10s)) << log();
  const auto first_beat = master_->from(0x706).front().at;
  ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x706).size() >= 7; }, 10s)) << log();
  for (const auto& s : master_->from(0x01ABCDE6, true)) {
    EXPECT_LT(s.at, first_beat) << "a TPDO with its COB-ID not valid";
  }
  EXPECT_TRUE(master_->from(0x186).empty());
}

// Puller 1.0 (mapping rw, as CiA 301): TPDO2 remapped with the CiA 301 sequence; the frame follows.
TEST_F(SimConformance, RemappedTpdoCarriesTheNewLayout) {
  start_sim({{"puller", kPuller}});
  write(kPuller, 0x6002, 0, 0x1234, 2);  // speed set value; the echo (6004h) follows it
  master_->nmt(kStart, kPuller);
  master_->clear();
  master_->syncs(3, 20ms);
  ASSERT_TRUE(master_->wait_for([&] { return !master_->from(0x288).empty(); }, 1s)) << log();
  // Default 1A01h: 6004 00 10h (echo), 6008 00 20h (product speed, 0: the drive does not run).
  EXPECT_EQ(bytes(master_->from(0x288).back().frame), (std::vector<std::uint8_t>{0x34, 0x12, 0x00, 0x00, 0x00, 0x00}));

  // The COB-ID is ro, so the PDO stays valid: no remapping while operational.
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 0, 0, 1), kDeviceState);
  master_->nmt(kPreOperational, kPuller);
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 1, 0x60080020, 4), kRange) << "sub 0 is not 0";
  write(kPuller, 0x1A01, 0, 0, 1);
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 1, 0x7FFF0010, 4), kNoObject);
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 1, 0x60040020, 4), kCannotMap) << "6004h is 16 bits";
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 1, 0x00060010, 4), kCannotMap) << "a dummy in a TPDO";
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 1, 0x10000020, 4), kCannotMap) << "1000h is no process value";
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 1, 0x10080008, 4), kCannotMap) << "a string";
  write(kPuller, 0x1A01, 1, 0x60080020, 4);
  write(kPuller, 0x1A01, 2, 0x60040010, 4);
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A01, 0, 3, 1), kRange) << "TPDO2 has two entries";
  write(kPuller, 0x1A01, 0, 2, 1);
  EXPECT_EQ(mapping(kPuller, 0x1A01), (Entries{0x60080020, 0x60040010}));
  // TPDO1 (3 entries): three 32-bit objects do not fit in 64 bits.
  write(kPuller, 0x1A00, 0, 0, 1);
  for (std::uint8_t sub = 1; sub <= 3; ++sub) write(kPuller, 0x1A00, sub, 0x60080020, 4);
  EXPECT_EQ(master_->write_abort(kPuller, 0x1A00, 0, 3, 1), kLengthExceeded);
  write(kPuller, 0x1A00, 0, 2, 1);

  master_->nmt(kStart, kPuller);
  master_->clear();
  master_->syncs(3, 20ms);
  ASSERT_TRUE(master_->wait_for([&] { return !master_->from(0x288).empty(); }, 1s)) << log();
  EXPECT_EQ(bytes(master_->from(0x288).back().frame), (std::vector<std::uint8_t>{0x00, 0x00, 0x00, 0x00, 0x34, 0x12}));
  ASSERT_FALSE(master_->from(0x188).empty());
  EXPECT_EQ(master_->from(0x188).back().frame.len, 8) << "TPDO1 now maps 6008h twice";
}

// What CiA 301 lets a master write of a PDO while it is valid (COB-ID bit 31 = 0), and what a
// device refuses then, as Lely CANopen's slave refuses it (its 1400h/1800h/1600h/1A00h download
// indications), every refusal with 0609 0030h "value range of parameter exceeded". Expected values
// by hand from CiA 301 7.5.2.35-7.5.2.38 (cia301-essentials.md) and the profiles' tables.

// Sub 1: a valid PDO keeps its identifier; its valid bit alone may change, in any NMT state.
TEST_F(SimConformance, CobIdOfAValidPdoKeepsItsIdentifier) {
  start_sim({{"puller_rw", kPullerRw}, {"corrugator", kCorrugator}});
  // Puller (9.1: CiA 301 rw COB-IDs) TPDO2 1801h: 4000 0280h + 0Ah, valid.
  EXPECT_EQ(read(kPullerRw, 0x1801, 1), 0x4000028Au);
  EXPECT_EQ(master_->write_abort(kPullerRw, 0x1801, 1, 0x40000290, 4), kRange) << "another identifier while valid";
  EXPECT_EQ(master_->write_abort(kPullerRw, 0x1801, 1, 0x6000028A, 4), kRange) << "bit 29 while valid";
  EXPECT_EQ(read(kPullerRw, 0x1801, 1), 0x4000028Au);
  write(kPullerRw, 0x1801, 1, 0xC000028A, 4);  // the same identifier, not valid
  EXPECT_EQ(read(kPullerRw, 0x1801, 1), 0xC000028Au);
  write(kPullerRw, 0x1801, 1, 0xC0000290, 4);  // not valid: another identifier may be set
  write(kPullerRw, 0x1801, 1, 0x40000290, 4);  // and made valid
  EXPECT_EQ(read(kPullerRw, 0x1801, 1), 0x40000290u);
  // Operational: the valid bit still toggles (corrugator 3.1 table 3: only it is writable).
  master_->nmt(kStart, kCorrugator);
  write(kCorrugator, 0x1800, 1, 0xC0000187, 4);
  EXPECT_EQ(read(kCorrugator, 0x1800, 1), 0xC0000187u);
  write(kCorrugator, 0x1800, 1, 0x40000187, 4);
  EXPECT_EQ(read(kCorrugator, 0x1800, 1), 0x40000187u);
}

// Sub 3: "shall not be changed while the PDO exists": refused while valid, in pre-operational and
// operational alike; written once the PDO is not valid. A PDO whose COB-ID the profile makes const
// (saw 3.1 tables 3 and 11) can never be made invalid, so its inhibit time is never written.
TEST_F(SimConformance, InhibitTimeOnlyWhileThePdoIsNotValid) {
  start_sim({{"corrugator", kCorrugator}, {"saw", kSaw}});
  EXPECT_EQ(read(kCorrugator, 0x1800, 3), 0u);
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1800, 3, 100, 2), kRange) << "pre-operational, valid";
  master_->nmt(kStart, kCorrugator);
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1800, 3, 100, 2), kRange) << "operational, valid";
  EXPECT_EQ(read(kCorrugator, 0x1800, 3), 0u);
  // The CiA 301 order: not valid, the inhibit time, valid again (here while operational).
  write(kCorrugator, 0x1800, 1, 0xC0000187, 4);
  write(kCorrugator, 0x1800, 3, 100, 2);
  write(kCorrugator, 0x1800, 1, 0x40000187, 4);
  EXPECT_EQ(read(kCorrugator, 0x1800, 3), 100u);
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1800, 3, 200, 2), kRange) << "valid again";
  EXPECT_EQ(read(kCorrugator, 0x1800, 3), 100u);
  // Saw 3.1: COB-ID const, always valid: TPDO1's and RPDO1's inhibit times are refused.
  EXPECT_EQ(master_->write_abort(kSaw, 0x1800, 3, 100, 2), kRange);
  EXPECT_EQ(master_->write_abort(kSaw, 0x1400, 3, 100, 2), kRange);
  EXPECT_EQ(read(kSaw, 0x1800, 3), 0u);
}

// Sub 2 and sub 5: a master may change a valid PDO's transmission type and event timer, also while
// the device is operational (CiA 301 puts no condition on them).
TEST_F(SimConformance, TransmissionTypeAndEventTimerOfAValidPdo) {
  start_sim({{"corrugator", kCorrugator}, {"saw", kSaw}});
  master_->nmt(kStart, kCorrugator);
  master_->nmt(kStart, kSaw);
  write(kCorrugator, 0x1800, 2, 254, 1);
  write(kCorrugator, 0x1800, 5, 300, 2);
  EXPECT_EQ(read(kCorrugator, 0x1800, 2), 254u);
  EXPECT_EQ(read(kCorrugator, 0x1800, 5), 300u);
  EXPECT_EQ(read(kCorrugator, 0x1800, 1), 0x40000187u) << "still valid";
  write(kSaw, 0x1801, 2, 2, 1);  // COB-ID const: valid for good, and still writable
  write(kSaw, 0x1801, 5, 250, 2);
  EXPECT_EQ(read(kSaw, 0x1801, 2), 2u);
  EXPECT_EQ(read(kSaw, 0x1801, 5), 250u);
}

// The mapping (sub 0 and the entries) changes only while the PDO is not valid and, for an entry,
// while sub 0 is 0 (CiA 301's sequence: not valid, sub 0 = 0, entries, sub 0 = n, valid).
TEST_F(SimConformance, MappingOnlyWhileThePdoIsNotValid) {
  start_sim({{"puller_rw", kPullerRw}, {"corrugator", kCorrugator}});
  // Puller 9.1 TPDO2 1A01h: 6004 00 10h, 6008 00 20h; valid, pre-operational.
  EXPECT_EQ(master_->write_abort(kPullerRw, 0x1A01, 0, 0, 1), kRange) << "sub 0 of a valid PDO";
  EXPECT_EQ(master_->write_abort(kPullerRw, 0x1A01, 1, 0x60080020, 4), kRange) << "an entry of a valid PDO";
  master_->nmt(kStart, kPullerRw);
  EXPECT_EQ(master_->write_abort(kPullerRw, 0x1A01, 0, 0, 1), kRange) << "operational, valid";
  master_->nmt(kPreOperational, kPullerRw);
  EXPECT_EQ(mapping(kPullerRw, 0x1A01), (Entries{0x60040010, 0x60080020}));
  write(kPullerRw, 0x1801, 1, 0xC000028A, 4);
  EXPECT_EQ(master_->write_abort(kPullerRw, 0x1A01, 1, 0x60080020, 4), kRange) << "not valid, but sub 0 is 2";
  write(kPullerRw, 0x1A01, 0, 0, 1);
  write(kPullerRw, 0x1A01, 1, 0x60080020, 4);
  write(kPullerRw, 0x1A01, 2, 0x60040010, 4);
  write(kPullerRw, 0x1A01, 0, 2, 1);
  write(kPullerRw, 0x1801, 1, 0x4000028A, 4);
  EXPECT_EQ(mapping(kPullerRw, 0x1A01), (Entries{0x60080020, 0x60040010}));
  // Corrugator 3.1 TPDO1, 1A00h sub 0 "rw (constant in NMT operational state)", 00h, 03h to 04h,
  // COB-ID valid bit writable: not while valid, even in pre-operational.
  EXPECT_EQ(master_->write_abort(kCorrugator, 0x1A00, 0, 4, 1), kRange);
  EXPECT_EQ(read(kCorrugator, 0x1A00, 0), 3u);
  write(kCorrugator, 0x1800, 1, 0xC0000187, 4);
  write(kCorrugator, 0x1A00, 0, 4, 1);
  write(kCorrugator, 0x1800, 1, 0x40000187, 4);
  EXPECT_EQ(read(kCorrugator, 0x1A00, 0), 4u);
}

// NMT reset node: every power-on value; reset communication: the communication objects only.
// Both drop pending RPDOs, and so does leaving operational. Stopped: no SDO answer at all.
TEST_F(SimConformance, NmtResetsRestorePowerOnValues) {
  start_sim({{"saw", kSaw}});
  const auto power_on_max = read(kSaw, 0x6006, 0);
  EXPECT_EQ(read(kSaw, 0x1017, 0), 100u) << "heartbeat_period_ms of the line file";
  const auto set_everything = [&] {
    write(kSaw, 0x1017, 0, 250, 2);
    write(kSaw, 0x1801, 2, 3, 1);
    write(kSaw, 0x1800, 5, 77, 2);  // the event timer: the inhibit time of a valid PDO cannot be written
    write(kSaw, 0x1A00, 0, 3, 1);
    write(kSaw, 0x6006, 0, 12345, 4);
  };
  const auto expect_communication_power_on = [&] {
    EXPECT_EQ(read(kSaw, 0x1017, 0), 100u);
    EXPECT_EQ(read(kSaw, 0x1801, 2), 1u);
    EXPECT_EQ(read(kSaw, 0x1800, 5), 0u);
    EXPECT_EQ(read(kSaw, 0x1A00, 0), 2u);
  };
  set_everything();
  master_->clear();
  master_->nmt(kResetCommunication, kSaw);
  ASSERT_TRUE(master_->wait_frame(0x705, is_boot_up, 2s)) << log();
  expect_communication_power_on();
  EXPECT_EQ(read(kSaw, 0x6006, 0), 12345u) << "reset communication keeps application values";

  set_everything();
  master_->clear();
  master_->nmt(kResetNode, kSaw);
  ASSERT_TRUE(master_->wait_frame(0x705, is_boot_up, 2s)) << log();
  expect_communication_power_on();
  EXPECT_EQ(read(kSaw, 0x6006, 0), power_on_max) << "reset node: the power-on value";

  // RPDO1 (200h + node-ID): 6020h control word, 6005h sync speed, 6002h product length (32 bit).
  const auto rpdo1 = [](std::uint32_t length) {
    return lb::can::make_frame(0x205, {0x00, 0x00, 0x00, 0x00, static_cast<std::uint8_t>(length),
                                       static_cast<std::uint8_t>(length >> 8), static_cast<std::uint8_t>(length >> 16),
                                       static_cast<std::uint8_t>(length >> 24)});
  };
  master_->nmt(kStart, kSaw);
  master_->send(rpdo1(12345));
  master_->syncs(2, 30ms);
  EXPECT_EQ(read(kSaw, 0x6002, 0), 12345u) << "synchronous RPDO taken at the SYNC";
  // Received, then a reset before the SYNC: never applied.
  master_->send(rpdo1(777));
  master_->nmt(kResetCommunication, kSaw);
  master_->nmt(kStart, kSaw);
  master_->syncs(3, 30ms);
  EXPECT_EQ(read(kSaw, 0x6002, 0), 12345u) << "an RPDO received before a reset was applied after it";
  // Received, then the device leaves operational: dropped too.
  master_->send(rpdo1(888));
  master_->nmt(kPreOperational, kSaw);
  master_->nmt(kStart, kSaw);
  master_->syncs(3, 30ms);
  EXPECT_EQ(read(kSaw, 0x6002, 0), 12345u) << "an RPDO received before leaving operational was applied";
  // Shorter than its mapping (8 bytes): not applied; EMCY 8210h, at most once a second.
  master_->clear();
  for (int i = 0; i < 4; ++i) master_->send(lb::can::make_frame(0x205, {0x00, 0x00, 0x00, 0x00, 0x01}));
  master_->syncs(3, 30ms);
  EXPECT_EQ(read(kSaw, 0x6002, 0), 12345u);
  const auto emcy = master_->from(0x085);
  ASSERT_EQ(emcy.size(), 1u) << log();
  EXPECT_EQ(emcy[0].frame.len, 8);
  EXPECT_EQ(emcy[0].frame.data[0], 0x10);
  EXPECT_EQ(emcy[0].frame.data[1], 0x82);

  // Stopped: the SDO server is silent, the client times out.
  master_->clear();
  master_->nmt(kStop, kSaw);
  // Stopped once its heartbeat says so (04h); the checks below count from there.
  ASSERT_TRUE(master_->wait_frame(
      0x705, [](const CanFrame& f) { return f.len == 1 && f.data[0] == 0x04; }, 10s))
      << log();
  master_->clear();
  const auto silent = master_->read(kSaw, 0x1000, 0);
  EXPECT_FALSE(silent.ok);
  EXPECT_EQ(silent.abort, kTimeout) << silent.message;
  for (const auto& s : master_->from(0x585)) ADD_FAILURE() << "an SDO answer while stopped: " << hex(s.frame.data[0]);
  EXPECT_FALSE(master_->from(0x705).empty());
  for (const auto& s : master_->from(0x705)) EXPECT_EQ(s.frame.data[0], 0x04) << "heartbeat: stopped";
  master_->nmt(kPreOperational, kSaw);
  EXPECT_EQ(read(kSaw, 0x1000, 0) & 0xFFFF, 0x01A4u);
}

// 1005h, 1014h, 1018h from simulation.identity, the device's own factory PDOs, a device that
// confirms writes and ignores them, and no heartbeat until 1017h is written.
TEST_F(SimConformance, CommunicationObjectsIdentityAndFaults) {
  start_sim({{"saw", kSaw}, {"saw2", kSaw2}});
  EXPECT_EQ(read(kSaw, 0x1005, 0), 0x80u) << "COB-ID SYNC";
  EXPECT_EQ(read(kSaw, 0x1014, 0), 0x85u) << "COB-ID EMCY: 80h + node-ID";
  EXPECT_EQ(read(kSaw, 0x1000, 0) & 0xFFFF, 0x01A4u) << "CiA 420";
  EXPECT_EQ(read(kSaw, 0x1018, 0), 4u);
  EXPECT_NE(read(kSaw, 0x1018, 1), 0x11111111u) << "the line's expected identity is the bridge's, not the device's";
  EXPECT_EQ(read(kSaw2, 0x1014, 0), 0x89u);
  EXPECT_EQ(read(kSaw2, 0x1000, 0), kSaw2DeviceType);
  EXPECT_EQ(read(kSaw2, 0x1018, 1), kSaw2Vendor);
  EXPECT_EQ(read(kSaw2, 0x1018, 2), kSaw2Product);
  EXPECT_EQ(read(kSaw2, 0x1018, 3), kSaw2Revision);
  EXPECT_EQ(read(kSaw2, 0x1018, 4), kSaw2Serial);
  // Its factory TPDO2: every 3rd SYNC, 6007h before 6001h; the line's type 7 never reaches it.
  EXPECT_EQ(read(kSaw2, 0x1801, 2), 3u);
  EXPECT_EQ(mapping(kSaw2, 0x1A01), (Entries{0x60070020, 0x60010020}));
  // Confirmed and ignored.
  const auto max = read(kSaw2, 0x6006, 0);
  write(kSaw2, 0x6006, 0, max + 1000, 4);
  EXPECT_EQ(read(kSaw2, 0x6006, 0), max);
  write(kSaw2, 0x1801, 2, 1, 1);
  EXPECT_EQ(read(kSaw2, 0x1801, 2), 3u);
  master_->nmt(kStart, kSaw2);
  master_->clear();
  master_->syncs(9, 20ms);
  EXPECT_TRUE(master_->wait_for([&] { return master_->from(0x289).size() >= 3; }, 10s)) << log();
  EXPECT_EQ(master_->from(0x289).size(), 3u) << "every 3rd SYNC";

  // heartbeat_period_ms 0: the boot-up, then nothing until a master writes 1017h. Measured
  // against the other saw's heartbeat (100 ms) on the same bus: five of them, and none of saw2.
  master_->clear();
  ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x705).size() >= 5; }, 10s))
      << "saw: heartbeat 100 ms" << log();
  EXPECT_TRUE(master_->from(0x709).empty());
  write(kSaw2, 0x1017, 0, 50, 2);
  master_->clear();
  // Eight heartbeats waited for, spaced by 50 ms by their send stamps (median of the gaps).
  ASSERT_TRUE(master_->wait_for([&] { return master_->from(0x709).size() >= 8; }, 10s)) << log();
  const auto beats = master_->from(0x709);
  std::vector<double> spacing;
  for (std::size_t i = 1; i < beats.size(); ++i) {
    spacing.push_back(static_cast<double>(beats[i].frame.timestamp_ns - beats[i - 1].frame.timestamp_ns) / 1e6);
  }
  EXPECT_GE(median(spacing), 50.0 - 20.0) << "1017h = 50 ms";
  EXPECT_LE(median(spacing), 50.0 + 75.0) << "1017h = 50 ms";
  for (const auto& s : beats) EXPECT_EQ(s.frame.data[0], 0x05) << "operational";
}

// 2002h: the simulator's silent reset. No boot-up message; heartbeats (pre-operational) go on.
TEST_F(SimConformance, SilentResetSendsNoBootUp) {
  start_sim({{"saw", kSaw}});
  // The saw's heartbeats (100 ms) after it confirmed the write of 2002h (the reset follows the
  // confirmation; the heartbeat period restarts with it): their states, and their send stamps.
  const auto heartbeats_after_confirmation = [this] {
    std::vector<CanFrame> beats;
    bool confirmed = false;
    for (const auto& s : master_->frames()) {
      const auto& f = s.frame;
      if (f.id == 0x585 && f.data[0] == 0x60 && f.data[1] == 0x02 && f.data[2] == 0x20) confirmed = true;
      if (f.id == 0x705 && is_boot_up(f)) ADD_FAILURE() << "a boot-up message";
      if (f.id == 0x705 && confirmed) beats.push_back(f);
    }
    return beats;
  };
  const auto power_on_max = read(kSaw, 0x6006, 0);
  master_->nmt(kStart, kSaw);
  write(kSaw, 0x1801, 2, 4, 1);
  write(kSaw, 0x6006, 0, 12345, 4);
  master_->clear();
  write(kSaw, 0x2002, 0, 2, 1);  // reset communication, silently
  // Three heartbeats after the reset (waited for: a loaded machine delays them, it does not make
  // them more or fewer), each pre-operational, and no boot-up among them.
  ASSERT_TRUE(master_->wait_for([&] { return heartbeats_after_confirmation().size() >= 3; }, 10s)) << log();
  auto beats = heartbeats_after_confirmation();
  for (const auto& f : beats) EXPECT_EQ(f.data[0], 0x7F) << "pre-operational";
  EXPECT_EQ(read(kSaw, 0x1801, 2), 1u);
  EXPECT_EQ(read(kSaw, 0x6006, 0), 12345u);
  master_->clear();
  master_->syncs(3, 20ms);
  // The marker: a heartbeat after the last SYNC (the device answers in order; a TPDO1 for a SYNC
  // would be before it).
  ASSERT_TRUE(master_->wait_for(
      [&] {
        bool after_sync = false;
        for (const auto& f : master_->frames()) {
          if (f.ours && f.frame.id == 0x080) {
            after_sync = false;
          } else if (!f.ours && f.frame.id == 0x705) {
            after_sync = true;
          }
        }
        return after_sync;
      },
      10s))
      << log();
  EXPECT_TRUE(master_->from(0x185).empty()) << "pre-operational: no PDO";

  master_->nmt(kStart, kSaw);
  master_->clear();
  write(kSaw, 0x2002, 0, 1, 1);  // reset node, silently
  // Five heartbeats after the reset, waited for (a loaded machine delays them). The reset node put
  // 1017h back to its power-on 100 ms: spaced by that period, by the frames' send stamps (the
  // median of the four gaps: one late frame lengthens one gap and shortens the next). A second
  // producer would halve the spacing, a lost period setting would stretch or stop it.
  ASSERT_TRUE(master_->wait_for([&] { return heartbeats_after_confirmation().size() >= 5; }, 10s)) << log();
  beats = heartbeats_after_confirmation();
  for (const auto& f : beats) EXPECT_EQ(f.data[0], 0x7F) << "pre-operational";
  std::vector<double> spacing;
  for (std::size_t i = 1; i < 5; ++i)
    spacing.push_back(static_cast<double>(beats[i].timestamp_ns - beats[i - 1].timestamp_ns) / 1e6);
  EXPECT_GE(median(spacing), 100.0 - 40.0) << "heartbeat period 100 ms" << log();
  EXPECT_LE(median(spacing), 100.0 + 150.0) << "heartbeat period 100 ms" << log();
  EXPECT_EQ(read(kSaw, 0x6006, 0), power_on_max);
  EXPECT_EQ(master_->write_abort(kSaw, 0x2002, 0, 3, 1), kRange);
  EXPECT_NE(sim_->log().find("without boot-up"), std::string::npos) << log();
}
