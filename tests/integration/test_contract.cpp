// The DDS contract as docs/dds-contract.md states it is what a running bridge announces; and everything the
// profiles define can be read or set over it: 6010h on info, saw wall-thickening, feeder digital
// outputs (RPDO3), objects beyond the typed status in other_values, bus-fault counters and a
// replay's diagnostics. The real bridge and simulator; expected values from the specs and the
// documentation (docs/), written here by hand.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

#include "msgs/corrugatorPubSubTypes.h"
#include "msgs/feederPubSubTypes.h"
#include "msgs/pullerPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/line_harness.hpp"
#include "support/line_views.hpp"
#include "support/set_value_client.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
namespace fdds = eprosima::fastdds::dds;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;
using lb::test::operational;

namespace {

// topic, registered type, direction (bridge writes: "bridge → apps"), reliability, durability.
using Endpoint = std::tuple<std::string, std::string, std::string, std::string, std::string>;

std::string trim(std::string s) {
  const auto a = s.find_first_not_of(" `");
  const auto b = s.find_last_not_of(" `");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

std::string registered(const std::string& type) {
  const bool service = type.find("_Request") != std::string::npos || type.find("_Response") != std::string::npos;
  return std::string("linebridge_msgs::") + (service ? "srv" : "msg") + "::dds_::" + type + "_";
}

// The page that holds the contract table, between these two markers.
constexpr const char* kContractPage = "docs/dds-contract.md";
constexpr const char* kTableBegin = "<!-- contract-table: begin -->";
constexpr const char* kTableEnd = "<!-- contract-table: end -->";

// The contract table, expanded for a line's devices (name -> device type). Every line between the
// markers must be the header, the separator or a well-formed row whose first column names
// `bridge`, `every device` or a device type of the line: a table the parser half-read, a row it
// could not read or a row no device of the test's line checks is an error, not a smaller table.
std::set<Endpoint> documented(const std::string& line, const std::map<std::string, std::string>& devices,
                              std::size_t& rows_read) {
  const std::string path = std::string(LB_SOURCE_DIR) + "/" + kContractPage;
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto begin = text.find(kTableBegin);
  const auto end = text.find(kTableEnd);
  if (begin == std::string::npos || end == std::string::npos || end < begin) {
    throw std::runtime_error(path + " has no contract table between its markers");
  }
  std::set<std::string> kinds{"bridge", "every device"};
  for (const auto& [name, kind] : devices) kinds.insert(kind);
  const std::set<std::string> directions{"bridge → apps", "apps → bridge"};
  const std::set<std::string> reliabilities{"reliable", "best-effort"};
  const std::set<std::string> durabilities{"volatile", "transient-local"};
  std::set<Endpoint> out;
  rows_read = 0;
  bool header = false;
  bool separator = false;
  std::istringstream rows(
      text.substr(begin + std::string(kTableBegin).size(), end - begin - std::string(kTableBegin).size()));
  for (std::string row; std::getline(rows, row);) {
    if (trim(row).empty()) continue;
    if (row.rfind("| for ", 0) == 0) {
      header = true;
      continue;
    }
    if (row.rfind("| ---", 0) == 0) {
      separator = true;
      continue;
    }
    if (row.rfind("| ", 0) != 0 || !header || !separator) throw std::runtime_error("not a contract row: " + row);
    std::vector<std::string> cells;
    std::stringstream cs(row.substr(1));
    for (std::string c; std::getline(cs, c, '|');) cells.push_back(trim(c));
    if (cells.size() < 7) throw std::runtime_error("contract row with too few cells: " + row);
    const auto& [who, topic, type, direction, reliability, durability] = std::tie(cells[0], cells[1], cells[2],
                                                                                  cells[3], cells[4], cells[5]);
    if (kinds.count(who) == 0)
      throw std::runtime_error("contract row for '" + who + "', which the test's line lacks: " + row);
    if (directions.count(direction) == 0 || reliabilities.count(reliability) == 0 ||
        durabilities.count(durability) == 0 || topic.find("<line>") == std::string::npos || type.empty()) {
      throw std::runtime_error("contract row not understood: " + row);
    }
    ++rows_read;
    for (const auto& [name, kind] : devices) {
      if (who != "bridge" && who != "every device" && who != kind) continue;
      std::string t = std::regex_replace(topic, std::regex("<line>"), line);
      t = std::regex_replace(t, std::regex("<device>"), name);
      out.insert({t, registered(type), direction, reliability, durability});
      if (who == "bridge") break;  // once per line
    }
  }
  return out;
}

// Every endpoint another participant announces, from DDS discovery.
class Announced : public fdds::DomainParticipantListener {
 public:
  void on_publisher_discovery(fdds::DomainParticipant*, eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override {
    if (info.status != eprosima::fastrtps::rtps::WriterDiscoveryInfo::DISCOVERED_WRITER) return;
    add(info.info.topicName().to_string(), info.info.typeName().to_string(), "bridge → apps",
        info.info.m_qos.m_reliability.kind, info.info.m_qos.m_durability.kind);
  }
  void on_subscriber_discovery(fdds::DomainParticipant*,
                               eprosima::fastrtps::rtps::ReaderDiscoveryInfo&& info) override {
    if (info.status != eprosima::fastrtps::rtps::ReaderDiscoveryInfo::DISCOVERED_READER) return;
    add(info.info.topicName().to_string(), info.info.typeName().to_string(), "apps → bridge",
        info.info.m_qos.m_reliability.kind, info.info.m_qos.m_durability.kind);
  }
  std::set<Endpoint> endpoints() {
    std::lock_guard lock(m_);
    return endpoints_;
  }

 private:
  void add(std::string topic, std::string type, std::string direction, fdds::ReliabilityQosPolicyKind r,
           fdds::DurabilityQosPolicyKind d) {
    std::lock_guard lock(m_);
    endpoints_.insert({std::move(topic), std::move(type), std::move(direction),
                       r == fdds::RELIABLE_RELIABILITY_QOS ? "reliable" : "best-effort",
                       d == fdds::TRANSIENT_LOCAL_DURABILITY_QOS
                           ? "transient-local"
                           : (d == fdds::VOLATILE_DURABILITY_QOS ? "volatile" : "other")});
  }
  std::mutex m_;
  std::set<Endpoint> endpoints_;
};

std::string describe(const std::set<Endpoint>& s) {
  std::string out;
  for (const auto& [t, ty, d, r, du] : s) out += "  " + t + " " + ty + " " + d + " " + r + " " + du + "\n";
  return out;
}

const std::string kDevices = "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n"
                             "  - {name: puller1, bus: b, node_id: 6, profile: cia420-2, version: '1.0'}\n"
                             "  - {name: corr1, bus: b, node_id: 7, profile: cia420-3, version: '3.1'}\n"
                             "  - {name: box1, bus: b, node_id: 10, profile: cia414-2, version: '1.1'}\n";

}  // namespace

TEST(Contract, TheContractTableIsWhatTheBridgeAnnounces) {
  lb::test::LineHarness line("contract", 27);
  Announced announced;
  // A plain Fast DDS participant: only DDS discovery tells what the bridge announces.
  const auto remove = [](fdds::DomainParticipant* p) {
    fdds::DomainParticipantFactory::get_instance()->delete_participant(p);
  };
  std::unique_ptr<fdds::DomainParticipant, decltype(remove)> participant(
      fdds::DomainParticipantFactory::get_instance()->create_participant(
          27, lb::ddsl::participant_qos({27, true, "contract-probe"}), &announced, fdds::StatusMask::none()),
      remove);
  ASSERT_NE(participant, nullptr);
  line.start(kDevices);
  std::size_t rows = 0;
  const auto expected = documented(
      "contract", {{"saw1", "saw"}, {"puller1", "puller"}, {"corr1", "corrugator"}, {"box1", "feeder"}}, rows);
  ASSERT_GT(rows, 0u) << kContractPage << ": the contract table has no rows";
  // Discovery is asynchronous: wait until the set stops growing and holds every documented one.
  lb::test::eventually(60s, [&] {
    const auto now = announced.endpoints();
    return std::all_of(expected.begin(), expected.end(), [&now](const auto& e) { return now.count(e) != 0; });
  });
  // Stays: a negative check after the positive marker (every documented endpoint announced): an
  // endpoint the table lacks would be announced with the others, and gets a second to show up.
  std::this_thread::sleep_for(1s);
  const auto seen = announced.endpoints();
  std::set<Endpoint> missing, undocumented;
  for (const auto& e : expected) {
    if (seen.count(e) == 0) missing.insert(e);
  }
  for (const auto& e : seen) {
    if (std::get<0>(e).find("/contract/") != std::string::npos && expected.count(e) == 0) undocumented.insert(e);
  }
  EXPECT_TRUE(missing.empty()) << "documented but not announced (or with another type or QoS):\n" << describe(missing);
  EXPECT_TRUE(undocumented.empty()) << "announced but not in " << kContractPage << "'s table:\n"
                                    << describe(undocumented);
}

// CiA 420 6010h: every named bit, on info, after the boot and on demand. Bit positions are
// profile-decisions.md's (saw 3.1: 0 speed measuring, 1 height adjustment, 2 cut depth, 3..5 f1..f3,
// 6 early warning, 7 corrugator cut management, 8 groove count mode); the simulated saw has a
// measuring wheel, cut depth, early warning and groove counting.
TEST(Contract, ConfigurationWordIsOnInfoBitByBit) {
  lb::test::LineHarness line("config6010", 28);
  line.start(kDevices);
  std::map<std::string, lb::test::Collector<msg::DeviceInfoPubSubType>> info;
  for (const char* d : {"saw1", "puller1", "corr1", "box1"})
    ASSERT_TRUE(info[d].subscribe(line.dds(), line.topic(d, "info"), QosKind::state));
  const auto started = [](const msg::DeviceInfo& i) { return i.started(); };
  for (auto& [d, c] : info) ASSERT_TRUE(c.wait_last(30s, started)) << d << "\n" << line.logs();

  const auto flags = [](const msg::DeviceInfo& i) {
    std::vector<std::tuple<std::string, int, bool>> out;
    for (const auto& f : i.configuration_word().flags()) out.emplace_back(f.name(), f.bit(), f.on());
    return out;
  };
  const auto saw = info["saw1"].samples().back();
  ASSERT_TRUE(saw.configuration_word().read()) << saw.configuration_word().remark();
  EXPECT_EQ(saw.configuration_word().raw(), 0x145u);
  EXPECT_EQ(flags(saw), (std::vector<std::tuple<std::string, int, bool>>{{"speed_measuring", 0, true},
                                                                         {"height_adjustment", 1, false},
                                                                         {"cut_depth", 2, true},
                                                                         {"f1_available", 3, false},
                                                                         {"f2_available", 4, false},
                                                                         {"f3_available", 5, false},
                                                                         {"early_warning", 6, true},
                                                                         {"corrugator_cut_management", 7, false},
                                                                         {"groove_count_mode", 8, true}}));
  const auto puller = info["puller1"].samples().back();
  EXPECT_EQ(puller.configuration_word().raw(), 0x1u);
  EXPECT_EQ(flags(puller), (std::vector<std::tuple<std::string, int, bool>>{{"speed_measuring", 0, true}}));
  const auto corr = info["corr1"].samples().back();
  EXPECT_EQ(corr.configuration_word().raw(), 0x7Fu);  // the simulated corrugator has all seven
  EXPECT_EQ(corr.configuration_word().flags().size(), 7u);
  const auto box = info["box1"].samples().back();
  EXPECT_FALSE(box.configuration_word().read());
  EXPECT_NE(box.configuration_word().remark().find("no configuration word"), std::string::npos);

  // On demand: get_parameter reads 6010h and info tells it again.
  const auto before = info["saw1"].size();
  using GetClient = lb::ddsl::ServiceClient<srv::GetParameter_RequestPubSubType, srv::GetParameter_ResponsePubSubType>;
  std::unique_ptr<GetClient> get;
  srv::GetParameter_Request req;
  req.device("saw1");
  req.parameter("configuration_word");
  const auto r = line.call(get, "get_parameter", req);
  ASSERT_TRUE(r.success()) << r.message();
  EXPECT_EQ(r.raw(), 0x145);
  EXPECT_TRUE(info["saw1"].wait(5s, [before](const auto& v) {
    return v.size() > before && v.back().configuration_word().raw() == 0x145;
  }));
}

// Saw control bit 1 (wall-thickening active) is a level the MES sets with the other set values.
TEST(Contract, SawWallThickeningIsASetValue) {
  lb::test::LineHarness line("wall", 29);
  line.start("  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n");
  lb::test::SetValueClient<msg::SawStatusPubSubType, msg::SawSetpointPubSubType> saw(line, "saw1");
  for (const bool on : {true, false}) {
    msg::SawSetpoint sp;
    sp.request_id(on ? 1 : 2);
    sp.saw_program_on(true);
    sp.wall_thickening(on);
    sp.sync_speed_percent(50);
    sp.product_length_m(1.0);
    line.spy().clear();
    ASSERT_TRUE(saw.writer.write(sp));
    ASSERT_TRUE(
        saw.results.wait(30s, [&](const auto& v) { return !v.empty() && v.back().request_id() == sp.request_id(); }));
    EXPECT_TRUE(saw.results.samples().back().accepted()) << saw.results.samples().back().reason();
    // RPDO1 (203h): 6020h bit 0 program on, bit 1 wall-thickening.
    ASSERT_TRUE(
        saw.status.wait_last(30s, [on](const msg::SawStatus& s) { return s.control_word().wall_thickening() == on; }));
    ASSERT_TRUE(line.spy().wait_until([on](const std::vector<lb::can::CanFrame>& frames) {
      return std::any_of(frames.begin(), frames.end(),
                         [on](const auto& f) { return f.id == 0x203 && (f.data[0] & 0x03) == (on ? 0x03 : 0x01); });
    })) << "no RPDO1 with the set value";
    const auto frames = line.spy().frames(0x203);
    EXPECT_EQ(frames.back().data[0] & 0x03, on ? 0x03 : 0x01);
  }
}

// Objects a device maps beyond the typed status: named in the line file, published by name and
// in engineering units, whether the line maps them (configure) or the device does (adopt).
TEST(Contract, MappedObjectsBeyondTheTypedStatusArePublishedByName) {
  lb::test::LineHarness line("other", 30);
  const std::string objects = "    objects: [{index: 0x2110, name: second_status_word, type: UNSIGNED16}]\n";
  line.start("  - name: saw1\n    bus: b\n    node_id: 3\n    profile: cia420-4\n    version: '3.1'\n" + objects +
             "    pdos: {tpdo1: {mapping: [0x60300010, 0x60000020, 0x21100010]}}\n"
             "  - name: saw2\n    bus: b\n    node_id: 4\n    profile: cia420-4\n    version: '3.1'\n" +
             objects +
             "    pdo_config: adopt\n"
             "    simulation: {pdos: {tpdo1: {mapping: [0x60300010, 0x60000020, 0x21100010]}}}\n");
  for (const char* dev : {"saw1", "saw2"}) {
    SCOPED_TRACE(dev);
    auto status = line.collect<msg::SawStatusPubSubType>(dev, "status", QosKind::state);
    ASSERT_TRUE(status.wait_last(30s, [](const msg::SawStatus& s) {
      return operational(s) && s.other_values().size() == 1 && s.other_values()[0].raw() > 2;
    })) << line.logs();
    const auto v = status.samples().back().other_values()[0];
    EXPECT_EQ(v.name(), "second_status_word");
    EXPECT_EQ(v.index(), 0x2110);
    EXPECT_EQ(v.sub_index(), 0);
    EXPECT_EQ(v.pdo(), "tpdo1");
    EXPECT_DOUBLE_EQ(v.value(), static_cast<double>(v.raw()));
    // The value is TPDO1's bytes 6..7 (after 6030h and 6000h), as the bus carried them.
    const auto node = std::string(dev) == "saw1" ? 3 : 4;
    bool on_bus = false;
    for (const auto& f : line.spy().frames(0x180 + node)) {
      if (f.len == 8 && (f.data[6] | f.data[7] << 8) == v.raw()) on_bus = true;
    }
    EXPECT_TRUE(on_bus) << "no TPDO1 carried " << v.raw();
  }
}

// Feeder RPDO3 (600Dh digital outputs, optional): typed in the loom set value when the box has it.
TEST(Contract, FeederDigitalOutputsGoInRpdo3WhenTheBoxHasIt) {
  lb::test::LineHarness line("outputs", 31);
  line.start("  - {name: box1, bus: b, node_id: 10, profile: cia414-2, version: '1.1'}\n"
             "  - {name: box2, bus: b, node_id: 11, profile: cia414-2, version: '1.1', pdos: {rpdo3: {cob_id: "
             "0x8000040B}}}\n");
  auto box1 = line.collect<msg::FeederStatusPubSubType>("box1", "status", QosKind::state);
  auto results = line.collect<msg::SetpointResultPubSubType>("box1", "loom_result", QosKind::reply);
  ASSERT_TRUE(results.subscribe(line.dds(), line.topic("box2", "loom_result"), QosKind::reply));
  auto w1 = line.dds().writer<msg::LoomSetpointPubSubType>(line.topic("box1", "loom"), QosKind::command);
  auto w2 = line.dds().writer<msg::LoomSetpointPubSubType>(line.topic("box2", "loom"), QosKind::command);
  ASSERT_TRUE(w1 && w2);
  ASSERT_TRUE(box1.wait_last(30s, operational<msg::FeederStatus>)) << line.logs();
  auto box2 = line.operational_status<msg::FeederStatusPubSubType>("box2");
  ASSERT_TRUE(line.wait_matched(*w1, line.topic("box1", "loom_result"))) << line.logs();
  ASSERT_TRUE(line.wait_matched(*w2, line.topic("box2", "loom_result"))) << line.logs();

  msg::LoomSetpoint sp;
  sp.request_id(7);
  sp.digital_outputs({0x81, 0x02});  // group 1: lines 1 and 8 on; group 2: line 2 on
  ASSERT_TRUE(w1->write(sp));
  ASSERT_TRUE(results.wait(5s, [](const auto& v) { return !v.empty() && v.back().request_id() == 7; }));
  EXPECT_TRUE(results.samples().back().accepted()) << results.samples().back().reason();
  ASSERT_TRUE(box1.wait_last(2s, [](const msg::FeederStatus& s) {
    return s.loom().digital_outputs() == std::vector<std::uint8_t>{0x81, 0x02, 0, 0, 0, 0, 0, 0};
  }));
  // RPDO3 of node 10 with the outputs, waited for on the bus.
  ASSERT_TRUE(line.spy().wait_until([](const std::vector<lb::can::CanFrame>& frames) {
    return std::any_of(frames.begin(), frames.end(), [](const auto& f) { return f.id == 0x40A && f.data[0] == 0x81; });
  })) << "RPDO3 not sent";
  const auto frames = line.spy().frames(0x40A);
  ASSERT_FALSE(frames.empty()) << "RPDO3 not sent";
  EXPECT_EQ(frames.back().len, 8);
  EXPECT_EQ(frames.back().data[0], 0x81);
  EXPECT_EQ(frames.back().data[1], 0x02);
  EXPECT_EQ(line.read_unsigned("box1", 0x600D, 1, "UNSIGNED8"), 0x81u) << "the box did not take the outputs";

  sp.request_id(8);
  ASSERT_TRUE(w2->write(sp));
  ASSERT_TRUE(results.wait(5s, [](const auto& v) { return !v.empty() && v.back().request_id() == 8; }));
  EXPECT_FALSE(results.samples().back().accepted());
  EXPECT_NE(results.samples().back().reason().find("RPDO3"), std::string::npos) << results.samples().back().reason();
  EXPECT_TRUE(line.spy().frames(0x40B).empty());
  EXPECT_TRUE(box2.samples().back().loom().digital_outputs().empty());
}

// Bus-fault counters are published; a replayed bus (log:) shows heartbeat ages on the recording's
// clock, and no load for a fast replay (frames come as fast as they are read).
TEST(Contract, ReplayDiagnosticsAreOnTheRecordingsClockAndCountRecordedFaults) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string dir = ::testing::TempDir();
  const std::string tag = std::to_string(::getpid());
  const std::string log = dir + "/replay_" + tag + ".log";
  {
    // 2021-01-01: heartbeats of nodes 3 and 4 every 100 ms for 2 s (4 one recorded period behind),
    // then a controller error-counter report (TEC 7Fh, REC 20h) and a bus-off.
    std::ofstream out(log);
    const auto at = [](long us) {
      return fmt::format("({}.{:06}) can0 ", 1609459200 + us / 1'000'000, us % 1'000'000);
    };
    for (long i = 0; i < 20; ++i) {
      out << at(i * 100'000) << "703#05\n";
      out << at(i * 100'000 + 5'000) << "704#05\n";
    }
    out << at(2'000'000) << "20000200#0000000000007F20\n";
    out << at(2'100'000) << "20000040#0000000000000000\n";
    for (long i = 0; i < 3; ++i) out << at(2'200'000 + i * 100'000) << "703#05\n";
  }
  const std::string config = dir + "/replay_" + tag + ".yaml";
  std::ofstream(config)
      << "line: replay\ndds: {domain: 32}\nbuses:\n"
         "  - {name: b, interface: 'log:" +
             log +
             "?pace=fast'}\n"
             "devices:\n"
             "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 60000}\n"
             "  - {name: saw2, bus: b, node_id: 4, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 60000}\n";
  lb::test::ChildProcess bridge({LB_BIN_BRIDGE, "--config", config}, dir + "/replay_bridge_" + tag + ".log");
  lb::test::Collector<msg::DiagnosticsPubSubType> diag;  // outlives the participant that calls it
  auto created = lb::ddsl::Participant::create({32, true, "replay-test"});
  ASSERT_TRUE(created);
  auto dds = std::move(*created);
  ASSERT_TRUE(diag.subscribe(*dds, lb::ddsl::topic_name("replay", "bridge", "diagnostics"), QosKind::state));
  ASSERT_TRUE(diag.wait_last(15s, [](const msg::Diagnostics& d) {
    return d.buses().size() == 1 && d.buses()[0].bus_offs() == 1 && d.nodes().size() == 2 &&
           d.nodes()[0].last_heartbeat_age_s() >= 0;
  })) << bridge.log();
  const auto d = diag.samples().back();
  const auto& b = d.buses()[0];
  EXPECT_TRUE(b.replay());
  EXPECT_EQ(b.load_percent(), -1.0) << "a fast replay has no wall-clock load";
  EXPECT_EQ(b.tx_error_counter(), 0x7F);
  EXPECT_EQ(b.rx_error_counter(), 0x20);
  EXPECT_EQ(b.bus_offs(), 1u);
  // saw1's last heartbeat is the newest (2.4 s into the recording), saw2's 1.905 s into it.
  for (const auto& n : d.nodes()) {
    const double expected = n.device() == "saw1" ? 0.0 : 0.495;
    EXPECT_NEAR(n.last_heartbeat_age_s(), expected, 1e-3) << n.device();
  }
  dds.reset();
  EXPECT_EQ(bridge.stop(), 0) << bridge.log();
}
