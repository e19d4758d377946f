// Line configuration: a good file loads; every kind of mistake stops start-up with the file,
// line and column and what is wrong.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <utility>

#include "profiles/line_config.hpp"

using lb::profiles::parse_line_config;
using lb::profiles::ProfileRegistry;

namespace {

const std::string kGood = R"(line: test
dds:
  domain: 7
  localhost_only: true
buses:
  - name: ext
    interface: virtual:x
    role: master
    sync_period_ms: 10
  - name: mon
    interface: socketcan:can1
    role: monitor
devices:
  - name: saw1
    bus: ext
    node_id: 3
    profile: cia420-4
    version: "3.1"
    heartbeat_timeout_ms: 300
    simulation:
      max_speed_m_per_min: 12.5
)";

std::string error_of(const std::string& yaml) {
  const auto registry = ProfileRegistry::builtin();
  auto r = parse_line_config(yaml, "line.yaml", registry);
  EXPECT_FALSE(r) << "accepted:\n" << yaml;
  return r ? std::string() : r.error().message;
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return pos == std::string::npos ? text : text.replace(pos, from.size(), to);
}

}  // namespace

TEST(LineConfig, GoodFileLoads) {
  const auto registry = ProfileRegistry::builtin();
  auto r = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->line, "test");
  EXPECT_EQ(r->dds.domain, 7u);
  ASSERT_EQ(r->buses.size(), 2u);
  EXPECT_EQ(r->buses[0].sync_period, std::chrono::milliseconds(10));
  EXPECT_EQ(r->buses[1].role, lb::profiles::BusRole::monitor);
  EXPECT_EQ(r->buses[1].sync_period, std::chrono::milliseconds(20));  // CiA 420-1 default
  ASSERT_EQ(r->devices.size(), 1u);
  EXPECT_EQ(r->devices[0].node_id, 3);
  EXPECT_EQ(r->devices[0].heartbeat_timeout, std::chrono::milliseconds(300));
  EXPECT_DOUBLE_EQ(r->devices[0].simulation.max_speed_m_per_min, 12.5);
  ASSERT_NE(r->devices[0].resolved_profile, nullptr);
  EXPECT_EQ(r->devices[0].resolved_profile->device, "saw");
}

TEST(LineConfig, UnknownKeyNamesFileLineColumn) {
  const auto e = error_of(replace(kGood, "    heartbeat_timeout_ms: 300", "    heartbeat_timout_ms: 300"));
  EXPECT_NE(e.find("line.yaml:19:5: unknown key 'heartbeat_timout_ms' in device"), std::string::npos) << e;
}

TEST(LineConfig, MissingNodeIdIsRefused) {
  const auto e = error_of(replace(kGood, "    node_id: 3\n", ""));
  EXPECT_NE(e.find("line.yaml:14:5: device saw1: missing required key 'node_id'"), std::string::npos) << e;
}

TEST(LineConfig, UnknownProfileIsRefusedWithTheKnownOnes) {
  auto e = error_of(replace(kGood, "profile: cia420-4", "profile: cia420-9"));
  EXPECT_NE(e.find("line.yaml:17:14: device saw1: unknown profile cia420-9 version 3.1"), std::string::npos) << e;
  EXPECT_NE(e.find("cia420-4@3.1"), std::string::npos) << e;
  e = error_of(replace(kGood, "version: \"3.1\"", "version: \"9.9\""));
  EXPECT_NE(e.find("unknown profile cia420-4 version 9.9"), std::string::npos) << e;
}

TEST(LineConfig, OtherMistakes) {
  EXPECT_NE(error_of(replace(kGood, "node_id: 3", "node_id: 128"))
                .find("line.yaml:16:14: device saw1: node_id 128 is outside 1..127"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "node_id: 3", "node_id: three")).find("'node_id' has a value of the wrong type"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "bus: ext", "bus: nowhere")).find("no bus named 'nowhere'"), std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "role: monitor", "role: slave")).find("role must be master, standby or monitor"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "virtual:x", "udp:x"))
                .find("interface must be socketcan:<ifname>, virtual:<name> or log:<file>"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "name: saw1", "name: saw-1")).find("'saw-1' is not a valid name"),
            std::string::npos);
  EXPECT_NE(
      error_of(replace(kGood, "name: saw1", "name: bridge")).find("line.yaml:14:11: device name 'bridge' is reserved"),
      std::string::npos)
      << error_of(replace(kGood, "name: saw1", "name: bridge"));
  EXPECT_NE(error_of(replace(kGood, "max_speed_m_per_min: 12.5", "max_speed: 12.5"))
                .find("unknown key 'max_speed' in simulation"),
            std::string::npos);
  EXPECT_NE(error_of(kGood + "  - {name: saw2, bus: ext, node_id: 3, profile: cia420-4, version: \"3.1\"}\n")
                .find("node-ID 3 is already used by saw1 on bus ext"),
            std::string::npos);
  EXPECT_NE(error_of("line: [unclosed\n").find("line.yaml:2:1: YAML syntax error"), std::string::npos)
      << error_of("line: [unclosed\n");
  EXPECT_NE(error_of("- just\n- a list\n").find("must be a mapping"), std::string::npos);
}

// realtime_priority: the bus loop's SCHED_FIFO priority, 1..99, absent or 0 = normal scheduling.
TEST(LineConfig, RealtimePriorityOfABusLoop) {
  const auto registry = ProfileRegistry::builtin();
  auto r = parse_line_config(replace(kGood, "    sync_period_ms: 10\n",
                                     "    sync_period_ms: 10\n    realtime_priority: 40\n"),
                             "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->buses[0].realtime_priority, 40);
  EXPECT_EQ(r->buses[1].realtime_priority, 0);
  auto e = error_of(replace(kGood, "    sync_period_ms: 10\n", "    sync_period_ms: 10\n    realtime_priority: 100\n"));
  EXPECT_NE(e.find("line.yaml:10:24: bus ext: realtime_priority 100 is outside 0..99"), std::string::npos) << e;
  e = error_of(replace(kGood, "    sync_period_ms: 10\n", "    sync_period_ms: 10\n    realtime_priority: high\n"));
  EXPECT_NE(e.find("line.yaml:10:24: 'realtime_priority' has a value of the wrong type"), std::string::npos) << e;
}

TEST(LineConfig, PdoOverrides) {
  const auto registry = ProfileRegistry::builtin();
  const std::string pdos =
      "    pdos:\n"
      "      tpdo1: {cob_id: 0x80000183}\n"
      "      tpdo2: {cob_id: 0x20012345, transmission_type: 254, inhibit_time_100us: 10, event_timer_ms: 250}\n"
      "      rpdo1: {transmission_type: 0, mapping: [0x60200010, 0x00060010, 0x60020020]}\n";
  auto r = parse_line_config(replace(kGood, "    simulation:\n", pdos + "    simulation:\n"), "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  const auto& p = r->devices[0].pdos;
  ASSERT_EQ(p.size(), 3u);
  EXPECT_FALSE(p[0].enabled);
  EXPECT_EQ(p[0].can_id, 0x183u);
  EXPECT_TRUE(p[1].extended);
  EXPECT_EQ(p[1].can_id, 0x12345u);
  EXPECT_EQ(p[1].transmission_type, 254);
  EXPECT_EQ(p[1].inhibit, std::chrono::microseconds(1000));
  EXPECT_EQ(p[1].event_timer, std::chrono::milliseconds(250));
  EXPECT_EQ(p[1].cob_id_entry(), 0x20012345u);
  EXPECT_EQ(p[2].mapping[1].index, 0x0006);  // dummy UNSIGNED16
  EXPECT_EQ(p[2].transmission_type, 0);

  const auto bad = [&](const std::string& text) {
    return error_of(replace(kGood, "    simulation:\n", text + "    simulation:\n"));
  };
  EXPECT_NE(bad("    pdos: {tpdo9: {transmission_type: 1}}\n").find("has no PDO 'tpdo9' (tpdo1, tpdo2, rpdo1)"),
            std::string::npos);
  EXPECT_NE(bad("    pdos: {tpdo1: {cob_id: 0x800}}\n").find("must be below 800h"), std::string::npos);
  EXPECT_NE(bad("    pdos: {tpdo1: {transmission_type: 245}}\n").find("transmission_type 245 is reserved"),
            std::string::npos);
  EXPECT_NE(bad("    pdos: {tpdo1: {mapping: [0x60300020]}}\n").find("mapping entry length differs"),
            std::string::npos);
  EXPECT_NE(bad("    pdos: {tpdo1: {mapping: [0x70000010]}}\n").find("does not define"), std::string::npos);
  EXPECT_NE(bad("    pdos: {tpdo1: {mapping: [0x60000020, 0x60010020, 0x60070020]}}\n").find("64"), std::string::npos);
  EXPECT_NE(bad("    configure: [{object: counter_value, value: 1}]\n").find("counter_value is ro, not writable"),
            std::string::npos);
  EXPECT_NE(bad("    configure: [{object: saw_cut_depth, value: 70000}]\n").find("configure entry"), std::string::npos);
}

TEST(LineConfig, BridgeRefusesABadFileWithLocationAndNonZeroExit) {
  const std::string path = ::testing::TempDir() + "/bad_line.yaml";
  std::ofstream(path) << replace(kGood, "    heartbeat_timeout_ms: 300", "    colour: red");
  const std::string cmd = std::string(LB_BIN_BRIDGE) + " --config " + path + " 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  std::array<char, 256> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe) != nullptr) output += buf.data();
  const int status = ::pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
  EXPECT_NE(output.find(path + ":19:5: unknown key 'colour' in device"), std::string::npos) << output;
}

TEST(ProfileFile, BrokenProfilesAreRefusedWithLocation) {
  const std::string base = R"(profile: x
version: "1"
device: saw
device_type: 0x01A4
objects:
  - {index: 0x6030, name: status_word, type: UNSIGNED16, access: ro}
)";
  auto r = lb::profiles::parse_profile(base + "bitsets:\n  status_word:\n    object: 0x6030\n    bits: {a: 16}\n",
                                       "p.yaml");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("p.yaml:10:15: bit 16 does not exist in a 16-bit word"), std::string::npos)
      << r.error().message;
  r = lb::profiles::parse_profile(
      base + "pdos:\n  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60300020]}\n",
      "p.yaml");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("mapping entry length differs"), std::string::npos) << r.error().message;
  r = lb::profiles::parse_profile(replace(base, "UNSIGNED16", "UNSIGNED17"), "p.yaml");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("unknown data type 'UNSIGNED17'"), std::string::npos) << r.error().message;
  ASSERT_TRUE(lb::profiles::parse_profile(base, "p.yaml"));
}

TEST(LineConfig, MasterBootKeys) {
  const auto registry = ProfileRegistry::builtin();
  const std::string yaml = replace(kGood, "    heartbeat_timeout_ms: 300\n",
                                   "    heartbeat_timeout_ms: 300\n"
                                   "    identity: {device_type: 0x1A4, vendor_id: 0x4C420000, serial_number: 7}\n"
                                   "    pdo_config: adopt\n"
                                   "    on_state_unknown: reset_node\n"
                                   "    heartbeat_producer_ms: 200\n"
                                   "    configure:\n"
                                   "      - {object: saw_sync_speed_set_maximum, value: 45000}\n"
                                   "      - {index: 0x1010, sub: 1, type: UNSIGNED32, value: 1, verify: false}\n");
  auto r = parse_line_config(yaml, "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  const auto& d = r->devices[0];
  EXPECT_EQ(d.identity.device_type, 0x1A4u);
  EXPECT_EQ(d.identity.vendor_id, 0x4C420000u);
  EXPECT_FALSE(d.identity.product_code.has_value());
  EXPECT_FALSE(d.identity.revision.has_value());
  EXPECT_EQ(d.identity.serial_number, 7u);
  EXPECT_EQ(d.pdo_config, lb::profiles::PdoConfigMode::adopt);
  EXPECT_EQ(d.on_state_unknown, lb::profiles::StateUnknownAction::reset_node);
  ASSERT_TRUE(d.heartbeat_producer.has_value());
  EXPECT_EQ(d.heartbeat_producer->count(), 200);
  ASSERT_EQ(d.configure.size(), 2u);
  EXPECT_TRUE(d.configure[0].verify);
  EXPECT_FALSE(d.configure[1].verify);

  // Defaults: configure the device, reboot it on an unknown state, keep its own 1017h.
  auto plain = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->devices[0].pdo_config, lb::profiles::PdoConfigMode::configure);
  EXPECT_EQ(plain->devices[0].on_state_unknown, lb::profiles::StateUnknownAction::reboot);
  EXPECT_FALSE(plain->devices[0].heartbeat_producer.has_value());
}

TEST(LineConfig, MasterBootMistakes) {
  const std::string at = "    heartbeat_timeout_ms: 300\n";
  EXPECT_NE(error_of(replace(kGood, at, at + "    heartbeat_producer_ms: 300\n"))
                .find("heartbeat_producer_ms 300 must be below heartbeat_timeout_ms 300"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, at, at + "    pdo_config: take\n")).find("pdo_config must be configure"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, at, at + "    on_state_unknown: start\n"))
                .find("on_state_unknown must be reboot or reset_node"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, at, at + "    identity: {vendor: 1}\n")).find("unknown key 'vendor'"),
            std::string::npos);
  // CiA 301: an RPDO is synchronous (0..240) or event-driven (254/255); dummies only in RPDOs.
  EXPECT_NE(
      error_of(replace(kGood, at, at + "    pdos: {rpdo1: {transmission_type: 252}}\n")).find("is for TPDOs only"),
      std::string::npos);
  EXPECT_NE(error_of(replace(kGood, at, at + "    pdos: {tpdo1: {mapping: [0x00050010]}}\n"))
                .find("a TPDO cannot carry them"),
            std::string::npos);
}

TEST(LineConfig, SimulationDeviceKeys) {
  const auto registry = ProfileRegistry::builtin();
  const std::string yaml = replace(kGood, "      max_speed_m_per_min: 12.5\n",
                                   "      max_speed_m_per_min: 12.5\n"
                                   "      heartbeat_period_ms: 0\n"
                                   "      identity: {product_code: 0x04200002}\n"
                                   "      pdos: {tpdo2: {mapping: [0x60070020, 0x60010020], transmission_type: 3}}\n"
                                   "      ignore_writes: [{index: 0x1801, sub: 2}]\n");
  auto r = parse_line_config(yaml, "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  const auto& sim = r->devices[0].simulation;
  EXPECT_EQ(sim.heartbeat_period.count(), 0);
  EXPECT_EQ(sim.identity.product_code, 0x04200002u);
  ASSERT_EQ(sim.pdos.size(), 1u);
  EXPECT_EQ(sim.pdos[0].name, "tpdo2");
  EXPECT_EQ(sim.pdos[0].transmission_type, 3);
  ASSERT_TRUE(sim.pdos[0].mapping.has_value());
  EXPECT_EQ(sim.pdos[0].mapping->front().index, 0x6007);
  EXPECT_EQ(sim.ignore_writes, (std::vector<std::uint32_t>{0x180102}));
  // The bridge's view of the PDOs stays the profile's: the simulation section is the device's.
  EXPECT_EQ(r->devices[0].pdos[1].mapping.front().index, 0x6001);
  EXPECT_NE(error_of(replace(yaml, "pdos: {tpdo2:", "pdos: {tpdo9:")).find("has no PDO 'tpdo9'"), std::string::npos);
}

// A device's own objects (a manufacturer-specific one it maps): the bridge decodes by the profile
// with them; the simulator keeps the profile as it is.
TEST(LineConfig, DeviceObjectsExtendTheBridgesProfileOnly) {
  const auto registry = ProfileRegistry::builtin();
  const std::string yaml = replace(
      kGood, "    heartbeat_timeout_ms: 300\n",
      "    heartbeat_timeout_ms: 300\n"
      "    objects:\n"
      "      - {index: 0x2110, name: second_status_word, type: UNSIGNED16}\n"
      "      - {index: 0x2120, name: blade_temperature, type: INTEGER16, unit: 0.1 °C, scale: 0.1, eng_unit: °C}\n"
      "    pdos: {tpdo1: {mapping: [0x60300010, 0x60000020, 0x21100010]}}\n");
  auto r = parse_line_config(yaml, "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  const auto& dev = r->devices[0];
  const auto* second = dev.bridge_profile().object("second_status_word");
  ASSERT_NE(second, nullptr);
  EXPECT_EQ(second->index, 0x2110);
  EXPECT_EQ(second->access, lb::profiles::Access::ro);
  const auto* blade = dev.bridge_profile().object(0x2120, 0);
  ASSERT_NE(blade, nullptr);
  EXPECT_DOUBLE_EQ(blade->to_engineering(0xFF9C), -10.0);  // -100 x 0.1 °C
  EXPECT_EQ(dev.resolved_profile->object("second_status_word"), nullptr) << "the simulator's profile changed";
  EXPECT_EQ(dev.pdos[0].mapping.size(), 3u);
  // Without objects: the mapping names an object the profile does not define.
  EXPECT_NE(error_of(replace(yaml, "      - {index: 0x2110, name: second_status_word, type: UNSIGNED16}\n", ""))
                .find("mapping entry names an object profile cia420-4@3.1 does not define"),
            std::string::npos);
  EXPECT_NE(error_of(replace(yaml, "name: second_status_word", "name: status_word")).find("already the profile's"),
            std::string::npos);
  EXPECT_NE(error_of(replace(yaml, "index: 0x2110", "index: 0x6030")).find("already status_word"), std::string::npos);
  EXPECT_NE(error_of(replace(yaml, "type: UNSIGNED16}", "type: UNSIGNED16, array: 3}")).find("unknown key 'array'"),
            std::string::npos);
}

TEST(LineConfig, SimulatedDeviceWithoutPreDefinedErrorField) {
  const auto registry = ProfileRegistry::builtin();
  auto r = parse_line_config(replace(kGood, "      max_speed_m_per_min: 12.5\n",
                                     "      max_speed_m_per_min: 12.5\n      pre_defined_error_field: false\n"),
                             "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_FALSE(r->devices[0].simulation.pre_defined_error_field);
  auto d = parse_line_config(kGood, "line.yaml", registry);
  EXPECT_TRUE(d->devices[0].simulation.pre_defined_error_field);
}

// ---- hostile files (issue 12): each was accepted, crashed or hung before ----------------------

namespace {

// The bridge's exit and what it printed, for a configuration file.
std::pair<int, std::string> run_bridge_with(const std::string& path) {
  const std::string cmd = std::string(LB_BIN_BRIDGE) + " --config " + path + " 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (pipe == nullptr) return {-1, "popen failed"};
  std::string output;
  std::array<char, 256> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe) != nullptr) output += buf.data();
  return {::pclose(pipe), output};
}

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "/line_config_" + std::to_string(::getpid()) + "_" + name;
}

std::string with_pdos(const std::string& pdos) {
  return replace(kGood, "    simulation:\n", pdos + "    simulation:\n");
}

}  // namespace

TEST(LineConfigHostile, NonScalarKeyIsAnErrorWithItsPlaceNotAnAbort) {
  // yaml-cpp's conversion of such a key threw YAML::TypedBadConversion past every handler.
  EXPECT_NE(error_of("? [a, b]\n: 1\n" + kGood).find("line.yaml:1:3: a key must be a plain value, not a list"),
            std::string::npos)
      << error_of("? [a, b]\n: 1\n" + kGood);
  EXPECT_NE(error_of(with_pdos("    pdos: {? {x: 1} : 2}\n")).find("a key must be a plain value, not a mapping"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "line: test\n", "line: test\n? &k a\n: 1\n? *k\n: 2\n")).find("not an alias"),
            std::string::npos);
  EXPECT_NE(error_of("{: 1}\n").find("a key must not be empty"), std::string::npos) << error_of("{: 1}\n");

  const auto path = temp_path("list_key.yaml");
  std::ofstream(path) << "? [a, b]\n: 1\n" << kGood;
  const auto [status, output] = run_bridge_with(path);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status) << ":\n" << output;
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_NE(output.find(path + ":1:3: a key must be a plain value"), std::string::npos) << output;
}

TEST(LineConfigHostile, LongNamesAreRefusedNotARecursionThatOverflowsTheStack) {
  // std::regex recursed once per character: ~100 kB overflowed the stack (SIGSEGV).
  const std::string huge(100'000, 'a');
  for (const auto& [from, to] : {std::pair<std::string, std::string>{"line: test", "line: " + huge},
                                 {"name: ext", "name: " + huge},
                                 {"name: saw1", "name: " + huge}}) {
    const auto e = error_of(replace(kGood, from, to));
    EXPECT_NE(e.find("is not a valid name"), std::string::npos) << e.substr(0, 300);
    EXPECT_NE(e.find("(100000 characters)"), std::string::npos) << "the message quotes the name cut short";
    EXPECT_LT(e.size(), 400u);
  }
  const auto registry = ProfileRegistry::builtin();
  EXPECT_TRUE(parse_line_config(replace(kGood, "name: saw1", "name: s" + std::string(63, 'x')), "line.yaml", registry));
  EXPECT_NE(error_of(replace(kGood, "name: saw1", "name: s" + std::string(64, 'x'))).find("at most 64 characters"),
            std::string::npos);
}

TEST(LineConfigHostile, DuplicateKeysAreRefusedWithBothPlaces) {
  // yaml-cpp keeps one of them silently: a line could run with the value its author did not mean.
  EXPECT_NE(error_of(replace(kGood, "    node_id: 3\n", "    node_id: 3\n    node_id: 4\n"))
                .find("line.yaml:17:5: key 'node_id' is given twice in this mapping (first at line 16, column 5)"),
            std::string::npos)
      << error_of(replace(kGood, "    node_id: 3\n", "    node_id: 3\n    node_id: 4\n"));
  EXPECT_NE(error_of("line: a\n" + kGood).find("line.yaml:2:1: key 'line' is given twice"), std::string::npos);
  EXPECT_NE(error_of(with_pdos("    pdos: {tpdo1: {transmission_type: 1}, tpdo1: {transmission_type: 2}}\n"))
                .find("key 'tpdo1' is given twice"),
            std::string::npos);
  // One document per file: YAML::Load read the first and ignored the rest.
  EXPECT_NE(error_of(kGood + "---\nline: other\n").find("one YAML document"), std::string::npos);
}

TEST(LineConfigHostile, DeepNestingAndAliasBombsAreRefused) {
  EXPECT_NE(error_of("line: " + std::string(5000, '[') + std::string(5000, ']') + "\n").find("nested more than"),
            std::string::npos);
  std::string bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n";
  for (char c = 'b'; c <= 'h'; ++c) {
    bomb += std::string(1, c) + ": &" + c + " [*" + static_cast<char>(c - 1);
    for (int i = 0; i < 9; ++i) bomb += std::string(", *") + static_cast<char>(c - 1);
    bomb += "]\n";
  }
  EXPECT_NE(error_of(bomb).find("aliases expanded"), std::string::npos) << error_of(bomb);
}

TEST(LineConfigHostile, OnlyRegularFilesOfBoundedSizeAreRead) {
  const auto registry = ProfileRegistry::builtin();
  // /dev/zero was read without end (~450 MB/s), a FIFO without a writer blocked start-up forever.
  auto r = lb::profiles::load_line_config("/dev/zero", registry);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("/dev/zero: line configuration: not a regular file"), std::string::npos)
      << r.error().message;
  const auto fifo = temp_path("fifo.yaml");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  r = lb::profiles::load_line_config(fifo, registry);
  ::unlink(fifo.c_str());
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("not a regular file"), std::string::npos) << r.error().message;
  r = lb::profiles::load_line_config(::testing::TempDir(), registry);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("not a regular file"), std::string::npos) << r.error().message;

  const auto big = temp_path("big.yaml");
  {
    std::ofstream out(big);
    out << kGood;
    const std::string comment = "# " + std::string(1000, '-') + "\n";
    for (int i = 0; i < 5000; ++i) out << comment;  // ~5 MB of comments
  }
  r = lb::profiles::load_line_config(big, registry);
  ::unlink(big.c_str());
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("larger than 4194304 bytes"), std::string::npos) << r.error().message;
  r = lb::profiles::load_line_config(temp_path("missing.yaml"), registry);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("cannot open"), std::string::npos) << r.error().message;
}

TEST(LineConfigHostile, TheAttacksHugeLineIsRefusedAtOnceAndBusesAreBounded) {
  // 254,000 devices on 2,000 buses loaded in quadratic time (every device compared with all before;
  // now a set per check). Such a file is now refused by its size, and a line by its number of buses.
  const auto registry = ProfileRegistry::builtin();
  const auto line = [](int buses, int per_bus) {
    std::string text = "line: big\nbuses:\n";
    for (int b = 0; b < buses; ++b)
      text += "  - {name: b" + std::to_string(b) + ", interface: \"virtual:b" + std::to_string(b) + "\"}\n";
    text += "devices:\n";
    for (int b = 0; b < buses; ++b) {
      for (int n = 1; n <= per_bus; ++n) {
        text += "  - {name: d" + std::to_string(b) + "_" + std::to_string(n) + ", bus: b" + std::to_string(b) +
                ", node_id: " + std::to_string(n) + ", profile: cia420-2, version: \"1.0\"}\n";
      }
    }
    return text;
  };
  auto r = parse_line_config(line(64, 20), "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->devices.size(), 64u * 20u);
  EXPECT_NE(error_of(line(65, 1)).find("a line has at most 64 buses"), std::string::npos);
  const auto huge = line(2000, 127);  // the attack's file: refused at once, not after minutes
  EXPECT_NE(error_of(huge).find("larger than 4194304 bytes"), std::string::npos);
}

TEST(LineConfigHostile, PdoIdentifiersOfRestrictedServicesAreRefused) {
  const auto e = [](const std::string& pdos) { return error_of(with_pdos(pdos)); };
  EXPECT_NE(e("    pdos: {rpdo1: {cob_id: 0x000}}\n")
                .find("line.yaml:20:28: pdo rpdo1 of device saw1: identifier 000h is NMT: CiA 301 restricts it"),
            std::string::npos)
      << e("    pdos: {rpdo1: {cob_id: 0x000}}\n");
  EXPECT_NE(e("    pdos: {tpdo1: {cob_id: 0x080}}\n").find("identifier 080h is SYNC"), std::string::npos);
  EXPECT_NE(e("    pdos: {tpdo1: {cob_id: 0x085}}\n").find("identifier 085h is EMCY"), std::string::npos);
  EXPECT_NE(e("    pdos: {tpdo1: {cob_id: 0x100}}\n").find("identifier 100h is TIME"), std::string::npos);
  EXPECT_NE(e("    pdos: {tpdo1: {cob_id: 0x583}}\n").find("default SDO (server to client)"), std::string::npos);
  EXPECT_NE(e("    pdos: {rpdo1: {cob_id: 0x603}}\n").find("default SDO (client to server)"), std::string::npos);
  EXPECT_NE(e("    pdos: {tpdo2: {cob_id: 0x703}}\n").find("NMT error control"), std::string::npos);
  for (const char* reserved : {"0x001", "0x07F", "0x101", "0x180", "0x6E0", "0x780", "0x7FF"}) {
    EXPECT_NE(
        e(std::string("    pdos: {tpdo1: {cob_id: ") + reserved + "}}\n").find("is reserved: CiA 301 restricts it"),
        std::string::npos)
        << reserved;
  }
  // A profile's default identifiers are checked too: profile files are input like the line.
  auto registry_with = ProfileRegistry::builtin();
  lb::profiles::Profile emcy_base = *registry_with.find("cia420-4", "3.1");
  emcy_base.id = "x-emcy";
  emcy_base.pdos[0].cob_id_base = 0x080;
  registry_with.add(emcy_base);
  auto r = parse_line_config(replace(kGood, "profile: cia420-4", "profile: x-emcy"), "line.yaml", registry_with);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("line.yaml:16:14: pdo " + emcy_base.pdos[0].name +
                                   " of device saw1: identifier 083h is EMCY"),
            std::string::npos)
      << r.error().message;
  // Not valid (bit 31) does not make it usable later; a 29-bit identifier is not restricted.
  EXPECT_NE(e("    pdos: {rpdo1: {cob_id: 0x80000000}}\n").find("is NMT"), std::string::npos);
  const auto registry = ProfileRegistry::builtin();
  EXPECT_TRUE(parse_line_config(
      with_pdos("    pdos: {tpdo1: {cob_id: 0x20000080}, tpdo2: {cob_id: 0x181}, rpdo1: {cob_id: 0x680}}\n"),
      "line.yaml", registry));
}

TEST(LineConfigHostile, OneIdentifierCarriesOnePdoOnABus) {
  const auto registry = ProfileRegistry::builtin();
  // saw1 (node 3) has TPDO1 on 183h; a second saw whose TPDO2 is moved there collides.
  const std::string second =
      "  - {name: saw2, bus: ext, node_id: 4, profile: cia420-4, version: \"3.1\", pdos: {tpdo2: {cob_id: 0x183}}}\n";
  auto e = error_of(kGood + second);
  EXPECT_NE(e.find("line.yaml:22:98: pdo tpdo2 of device saw2: identifier 183h is already used by pdo tpdo1 of device "
                   "saw1 on bus ext"),
            std::string::npos)
      << e;
  e = error_of(with_pdos("    pdos: {tpdo2: {cob_id: 0x203}}\n"));  // its own RPDO1's identifier
  EXPECT_NE(e.find("pdo rpdo1 of device saw1: identifier 203h is already used by pdo tpdo2 of device saw1"),
            std::string::npos)
      << e;
  e = error_of(with_pdos("    pdos: {tpdo1: {cob_id: 0x20000283}, tpdo2: {cob_id: 0x20000283}}\n"));
  EXPECT_NE(e.find("identifier 00000283h is already used"), std::string::npos) << e;
  // On another bus, not valid, or 11-bit against 29-bit: no collision.
  EXPECT_TRUE(parse_line_config(kGood + "  - {name: saw2, bus: mon, node_id: 3, profile: cia420-4, version: \"3.1\"}\n",
                                "line.yaml", registry));
  EXPECT_TRUE(parse_line_config(kGood + "  - {name: saw2, bus: ext, node_id: 4, profile: cia420-4, version: \"3.1\", "
                                        "pdos: {tpdo2: {cob_id: 0x80000183}}}\n",
                                "line.yaml", registry));
  EXPECT_TRUE(parse_line_config(with_pdos("    pdos: {tpdo2: {cob_id: 0x20000183}}\n"), "line.yaml", registry));
}

TEST(LineConfigHostile, ARecordingCannotBeAReplayedLogOrAnotherRecording) {
  const auto log = temp_path("replayed.log");
  const auto buses = "buses:\n  - {name: ext, interface: \"virtual:x\", record: \"" + log + "\"}\n" +
                     "  - {name: mon, interface: \"log:" + log + "\"}\n";
  const std::string devices = "devices: []\n";
  auto e = error_of("line: test\n" + buses + devices);
  EXPECT_NE(e.find("line.yaml:3:49: bus ext: record: '" + log + "' cannot be recorded into: bus mon replays it"),
            std::string::npos)
      << e;
  // The same file by another spelling.
  const auto dir = ::testing::TempDir();
  const auto other = dir + "/./" + log.substr(dir.size() + 1);
  e = error_of("line: test\nbuses:\n  - {name: mon, interface: \"log:" + log + "?pace=fast\", record: \"" + other +
               "\"}\n" + devices);
  EXPECT_NE(e.find("cannot be recorded into: bus mon replays it"), std::string::npos) << e;
  e = error_of("line: test\nbuses:\n  - {name: a, interface: \"virtual:x\", record: \"" + log +
               "\"}\n  - {name: b, interface: \"virtual:y\", record: \"" + log + "\"}\n" + devices);
  EXPECT_NE(e.find("bus b: record: '" + log + "' cannot be recorded into: bus a records into it"), std::string::npos)
      << e;
}

// The start-up policy: safe defaults (no restart after a power loss, speeds and lengths back, one
// hour), each key checked, and an automatic restart warned about.
TEST(LineConfig, StartupPolicyDefaultsAreSafeAndEachKeyIsChecked) {
  using lb::profiles::StartupPolicy;
  const auto registry = ProfileRegistry::builtin();
  auto plain = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(plain) << plain.error().message;
  EXPECT_EQ(plain->startup.restart_after_power_loss, StartupPolicy::Restart::never);
  EXPECT_EQ(plain->startup.after_power_loss, StartupPolicy::AfterPowerLoss::non_enabling);
  EXPECT_EQ(plain->startup.set_values_max_age, std::chrono::seconds(3600));
  EXPECT_FALSE(plain->devices[0].starts_itself);
  EXPECT_TRUE(plain->warnings.empty());

  const auto set = replace(
      kGood, "dds:\n",
      "startup: {set_values_max_age_s: 60, after_power_loss: nothing, restart_after_power_loss: allowed}\ndds:\n");
  auto custom = parse_line_config(replace(set, "    heartbeat_timeout_ms: 300\n",
                                          "    heartbeat_timeout_ms: 300\n    starts_itself: true\n"),
                                  "line.yaml", registry);
  ASSERT_TRUE(custom) << custom.error().message;
  EXPECT_EQ(custom->startup.restart_after_power_loss, StartupPolicy::Restart::allowed);
  EXPECT_EQ(custom->startup.after_power_loss, StartupPolicy::AfterPowerLoss::nothing);
  EXPECT_EQ(custom->startup.set_values_max_age, std::chrono::seconds(60));
  EXPECT_TRUE(custom->devices[0].starts_itself);
  ASSERT_EQ(custom->warnings.size(), 1u);
  EXPECT_NE(custom->warnings[0].find("restart_after_power_loss: allowed"), std::string::npos) << custom->warnings[0];

  EXPECT_NE(error_of(replace(kGood, "dds:\n", "startup: {restart_after_power_loss: always}\ndds:\n"))
                .find("must be never or allowed"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "dds:\n", "startup: {after_power_loss: all}\ndds:\n")).find("non_enabling"),
            std::string::npos);
  EXPECT_NE(
      error_of(replace(kGood, "dds:\n", "startup: {set_values_max_age_s: -1}\ndds:\n")).find("set_values_max_age_s"),
      std::string::npos);
  EXPECT_NE(error_of(replace(kGood, "dds:\n", "startup: {restore: true}\ndds:\n")).find("restore"), std::string::npos);
}

// Mandatory devices (CiA 302-2 1F81h bit 3): off by default, as 1F81h bit 3 is; the line's reaction
// when one fails defaults to stop_others; each value is checked; a monitor bus cannot have one
// (the bridge never starts or stops a device there); a reaction chosen with no mandatory device is
// warned about.
TEST(LineConfig, MandatoryDevicesAndWhatTheLineDoesWhenOneFails) {
  using lb::profiles::StartupPolicy;
  const auto registry = ProfileRegistry::builtin();
  auto plain = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(plain) << plain.error().message;
  EXPECT_FALSE(plain->devices[0].mandatory);
  EXPECT_EQ(plain->startup.when_mandatory_fails, StartupPolicy::WhenMandatoryFails::stop_others);

  const auto mandatory = replace(kGood, "    heartbeat_timeout_ms: 300\n",
                                 "    heartbeat_timeout_ms: 300\n    mandatory: true\n");
  auto m = parse_line_config(mandatory, "line.yaml", registry);
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_TRUE(m->devices[0].mandatory);
  EXPECT_EQ(m->startup.when_mandatory_fails, StartupPolicy::WhenMandatoryFails::stop_others);
  EXPECT_TRUE(m->warnings.empty());

  auto report = parse_line_config(replace(mandatory, "dds:\n", "startup: {when_mandatory_fails: report_only}\ndds:\n"),
                                  "line.yaml", registry);
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_EQ(report->startup.when_mandatory_fails, StartupPolicy::WhenMandatoryFails::report_only);
  auto stop = parse_line_config(replace(mandatory, "dds:\n", "startup: {when_mandatory_fails: stop_others}\ndds:\n"),
                                "line.yaml", registry);
  ASSERT_TRUE(stop) << stop.error().message;
  EXPECT_EQ(stop->startup.when_mandatory_fails, StartupPolicy::WhenMandatoryFails::stop_others);

  auto e = error_of(replace(mandatory, "dds:\n", "startup: {when_mandatory_fails: reset_all}\ndds:\n"));
  EXPECT_NE(e.find("line.yaml:2:"), std::string::npos) << e;
  EXPECT_NE(e.find("when_mandatory_fails must be stop_others"), std::string::npos) << e;
  EXPECT_NE(e.find("'reset_all'"), std::string::npos) << e;
  e = error_of(
      replace(kGood, "    heartbeat_timeout_ms: 300\n", "    heartbeat_timeout_ms: 300\n    mandatory: yes please\n"));
  EXPECT_NE(e.find("line.yaml:"), std::string::npos) << e;
  EXPECT_NE(e.find("mandatory"), std::string::npos) << e;
  e = error_of(
      replace(kGood, "    heartbeat_timeout_ms: 300\n", "    heartbeat_timeout_ms: 300\n    mandatory_device: true\n"));
  EXPECT_NE(e.find("mandatory_device"), std::string::npos) << e;

  // On the monitor bus: refused, with the place and the reason.
  const auto on_monitor = replace(mandatory, "    bus: ext\n", "    bus: mon\n");
  e = error_of(on_monitor);
  EXPECT_NE(e.find("line.yaml:"), std::string::npos) << e;
  EXPECT_NE(e.find("device saw1: mandatory is for a master or standby bus: bus mon is in the monitor role"),
            std::string::npos)
      << e;
  // mandatory: false is what a monitor bus's device is anyway.
  auto off = parse_line_config(replace(kGood, "    bus: ext\n    node_id: 3\n",
                                       "    bus: mon\n    node_id: 3\n    mandatory: false\n"),
                               "line.yaml", registry);
  ASSERT_TRUE(off) << off.error().message;

  // A reaction without a mandatory device: accepted, and --check says it does nothing.
  auto idle = parse_line_config(replace(kGood, "dds:\n", "startup: {when_mandatory_fails: report_only}\ndds:\n"),
                                "line.yaml", registry);
  ASSERT_TRUE(idle) << idle.error().message;
  ASSERT_EQ(idle->warnings.size(), 1u);
  EXPECT_NE(idle->warnings[0].find("no device is mandatory"), std::string::npos) << idle->warnings[0];
  EXPECT_NE(idle->warnings[0].find("line.yaml:"), std::string::npos) << idle->warnings[0];
}

// What the boot does with a running device whose PDO parameters must change: pre_operational by
// default (CiA 302-2: the master pauses it to write), keep_running on request; nothing else.
TEST(LineConfig, PdoChangeWhenRunningIsPreOperationalByDefault) {
  using lb::canopen::PdoChangeWhenRunning;
  const auto registry = ProfileRegistry::builtin();
  auto plain = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(plain) << plain.error().message;
  EXPECT_EQ(plain->startup.pdo_change_when_running, PdoChangeWhenRunning::pre_operational);
  auto keep = parse_line_config(replace(kGood, "dds:\n", "startup: {pdo_change_when_running: keep_running}\ndds:\n"),
                                "line.yaml", registry);
  ASSERT_TRUE(keep) << keep.error().message;
  EXPECT_EQ(keep->startup.pdo_change_when_running, PdoChangeWhenRunning::keep_running);
  EXPECT_TRUE(keep->warnings.empty());
  auto pre = parse_line_config(replace(kGood, "dds:\n", "startup: {pdo_change_when_running: pre_operational}\ndds:\n"),
                               "line.yaml", registry);
  ASSERT_TRUE(pre) << pre.error().message;
  EXPECT_EQ(pre->startup.pdo_change_when_running, PdoChangeWhenRunning::pre_operational);
  const auto e = error_of(replace(kGood, "dds:\n", "startup: {pdo_change_when_running: reset_node}\ndds:\n"));
  EXPECT_NE(e.find("pdo_change_when_running must be pre_operational"), std::string::npos) << e;
  // A misspelt key stays an error.
  EXPECT_NE(error_of(replace(kGood, "dds:\n", "startup: {pdo_change_while_running: keep_running}\ndds:\n"))
                .find("pdo_change_while_running"),
            std::string::npos);
}

// Saw 3.1 makes its TPDOs' COB-IDs const (tables 3, 7): valid for good, so CiA 301 forbids writing
// their inhibit time. A line that wants one is warned at --check (its boot would fail with J),
// unless it adopts the device's value.
TEST(LineConfig, InhibitTimeOfAPdoWithAConstCobIdIsWarnedAbout) {
  const auto registry = ProfileRegistry::builtin();
  const auto with = [&](const std::string& text) {
    return parse_line_config(replace(kGood, "    simulation:\n", text + "    simulation:\n"), "line.yaml", registry);
  };
  auto r = with("    pdos: {tpdo1: {transmission_type: 254, inhibit_time_100us: 500}}\n");
  ASSERT_TRUE(r) << r.error().message;
  ASSERT_EQ(r->warnings.size(), 1u);
  EXPECT_NE(r->warnings[0].find("tpdo1 inhibit_time_100us 500"), std::string::npos) << r->warnings[0];
  EXPECT_NE(r->warnings[0].find("fails with J"), std::string::npos) << r->warnings[0];
  r = with("    pdos: {tpdo1: {transmission_type: 254, event_timer_ms: 300}}\n");
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_TRUE(r->warnings.empty());
  r = with("    pdo_config: adopt\n    pdos: {tpdo1: {inhibit_time_100us: 500}}\n");
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_TRUE(r->warnings.empty());
}

// Two master buses on one CAN network would hear each other's SYNC and NMT and silence each other.
TEST(LineConfig, TwoMasterBusesOnOneInterfaceAreRefused) {
  const auto two = replace(kGood, "    interface: socketcan:can1\n    role: monitor\n",
                           "    interface: virtual:x\n    role: master\n");
  const auto e = error_of(two);
  EXPECT_NE(e.find("is already bus ext, and both are masters"), std::string::npos) << e;
  EXPECT_NE(e.find("line.yaml:11:"), std::string::npos) << e;
  // A monitor beside a master on one interface is fine (it only listens).
  const auto registry = ProfileRegistry::builtin();
  EXPECT_TRUE(
      parse_line_config(replace(kGood, "interface: socketcan:can1", "interface: virtual:x"), "line.yaml", registry));
}

// Devices of one bus that only 1000h bits 0..15 tell apart (a puller and a saw both answer 01A4h)
// are named: without identity: either is taken for the other at its node-ID.
TEST(LineConfig, DevicesToldApartByTheProfileNumberAloneAreNamed) {
  const auto registry = ProfileRegistry::builtin();
  const std::string puller = "  - {name: puller1, bus: ext, node_id: 4, profile: cia420-2, version: '1.0'}\n";
  auto both = parse_line_config(kGood + puller, "line.yaml", registry);
  ASSERT_TRUE(both) << both.error().message;
  ASSERT_EQ(both->warnings.size(), 1u);
  EXPECT_NE(both->warnings[0].find("bus ext: saw1, puller1 have no identity:"), std::string::npos) << both->warnings[0];
  EXPECT_NE(both->warnings[0].find("1000h bits 0..15 alone"), std::string::npos) << both->warnings[0];
  // With the saw's identity given, only the puller is named.
  auto one =
      parse_line_config(replace(kGood, "    heartbeat_timeout_ms: 300\n",
                                "    heartbeat_timeout_ms: 300\n    identity: {vendor_id: 1, product_code: 2}\n") +
                            puller,
                        "line.yaml", registry);
  ASSERT_TRUE(one) << one.error().message;
  ASSERT_EQ(one->warnings.size(), 1u);
  EXPECT_NE(one->warnings[0].find("bus ext: puller1 has no identity:"), std::string::npos) << one->warnings[0];
  // One device of a profile number on a bus: nothing to confuse it with there.
  auto single = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(single);
  EXPECT_TRUE(single->warnings.empty());
}

// A standby (docs/redundancy.md) watches the master's heartbeat on master_node_id and takes over
// after takeover_after_ms of silence: default 2.5 heartbeat periods, longer than one period, for
// the standby role only; a mandatory device is taken there as on a master bus.
TEST(LineConfig, StandbyRoleKeys) {
  const auto registry = ProfileRegistry::builtin();
  const auto standby = replace(kGood, "    role: master\n",
                               "    role: standby\n    master_node_id: 1\n    master_heartbeat_ms: 40\n"
                               "    flying_master: {priority: 3}\n");
  auto r = parse_line_config(standby, "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->buses[0].role, lb::profiles::BusRole::standby);
  EXPECT_EQ(r->buses[0].takeover_after, std::chrono::milliseconds(100));
  // CiA 302-2 1F90h: the priority given, the rest its defaults (sub 1, 2, 4, 5, 6).
  const auto& f = r->buses[0].flying;
  EXPECT_EQ(f.priority, 3);
  EXPECT_EQ(f.detect_timeout, std::chrono::milliseconds(100));
  EXPECT_EQ(f.negotiation_delay, std::chrono::milliseconds(500));
  EXPECT_EQ(f.priority_slot, std::chrono::milliseconds(1500));
  EXPECT_EQ(f.device_slot, std::chrono::milliseconds(10));
  EXPECT_EQ(f.detect_cycle, std::chrono::milliseconds(4000));
  r = parse_line_config(replace(standby, "{priority: 3}",
                                "{priority: 0, detect_timeout_ms: 7, negotiation_delay_ms: 8, priority_slot_ms: 9, "
                                "device_slot_ms: 11, detect_cycle_ms: 12}"),
                        "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->buses[0].flying.priority, 0);
  EXPECT_EQ(r->buses[0].flying.detect_timeout, std::chrono::milliseconds(7));
  EXPECT_EQ(r->buses[0].flying.negotiation_delay, std::chrono::milliseconds(8));
  EXPECT_EQ(r->buses[0].flying.priority_slot, std::chrono::milliseconds(9));
  EXPECT_EQ(r->buses[0].flying.device_slot, std::chrono::milliseconds(11));
  EXPECT_EQ(r->buses[0].flying.detect_cycle, std::chrono::milliseconds(12));
  auto bad = error_of(replace(standby, "    flying_master: {priority: 3}\n", ""));
  EXPECT_NE(bad.find("a standby negotiates mastership (CiA 302-2): it needs flying_master: {priority: N}"),
            std::string::npos)
      << bad;
  bad = error_of(replace(standby, "{priority: 3}", "{detect_cycle_ms: 100}"));
  EXPECT_NE(bad.find("flying_master needs priority"), std::string::npos) << bad;
  bad = error_of(replace(standby, "{priority: 3}", "{priority: 256}"));
  EXPECT_NE(bad.find("priority"), std::string::npos) << bad;
  EXPECT_NE(bad.find("255"), std::string::npos) << bad;
  bad = error_of(replace(standby, "{priority: 3}", "{priority: 3, slot_ms: 5}"));
  EXPECT_NE(bad.find("slot_ms"), std::string::npos) << bad;
  bad = error_of(replace(standby, "{priority: 3}", "{priority: 3, detect_cycle_ms: 0}"));
  EXPECT_NE(bad.find("detect_cycle_ms"), std::string::npos) << bad;
  bad = error_of(replace(kGood, "    role: master\n", "    role: master\n    flying_master: {priority: 1}\n"));
  EXPECT_NE(bad.find("flying_master is for the standby role"), std::string::npos) << bad;
  EXPECT_TRUE(lb::profiles::masters(r->buses[0].role));
  r = parse_line_config(replace(standby, "master_heartbeat_ms: 40\n",
                                "master_heartbeat_ms: 40\n    takeover_after_ms: 300\n"),
                        "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->buses[0].takeover_after, std::chrono::milliseconds(300));

  auto e = error_of(replace(kGood, "    role: master\n", "    role: standby\n"));
  EXPECT_NE(e.find("a standby watches the master's heartbeat and takes it over: it needs master_node_id"),
            std::string::npos)
      << e;
  e = error_of(replace(standby, "master_heartbeat_ms: 40\n", "master_heartbeat_ms: 40\n    takeover_after_ms: 40\n"));
  EXPECT_NE(e.find("takeover_after_ms 40 must be longer than the master's heartbeat period master_heartbeat_ms 40"),
            std::string::npos)
      << e;
  e = error_of(replace(kGood, "    role: master\n", "    role: master\n    takeover_after_ms: 300\n"));
  EXPECT_NE(e.find("takeover_after_ms is for the standby role"), std::string::npos) << e;
  // A mandatory device on a standby bus: taken as on a master bus (the takeover takes the line's
  // state from the bus; MandatoryDevices judges from then on), without a warning.
  r = parse_line_config(replace(standby, "    heartbeat_timeout_ms: 300\n",
                                "    heartbeat_timeout_ms: 300\n    mandatory: true\n"),
                        "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->buses[0].role, lb::profiles::BusRole::standby);
  EXPECT_EQ(r->devices[0].bus, r->buses[0].name);
  EXPECT_TRUE(r->devices[0].mandatory);
  EXPECT_TRUE(r->warnings.empty());
  // A standby and a master on one interface in one line file: two masters.
  e = error_of(replace(standby, "    interface: socketcan:can1\n    role: monitor\n",
                       "    interface: virtual:x\n    role: master\n"));
  EXPECT_NE(e.find("both are masters"), std::string::npos) << e;
}

// observability: the DDS process's status page and metrics, on loopback unless the file names an
// address; numeric addresses only; off serves nothing.
TEST(LineConfig, ObservabilityListen) {
  const auto registry = ProfileRegistry::builtin();
  auto r = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_TRUE(r->observability.enabled);
  EXPECT_EQ(r->observability.listen(), "127.0.0.1:9420");
  const auto with = [&](const std::string& value) {
    return replace(kGood, "dds:\n", "observability:\n  listen: " + value + "\ndds:\n");
  };
  r = parse_line_config(with("\"192.0.2.7:8080\""), "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->observability.address, "192.0.2.7");
  EXPECT_EQ(r->observability.port, 8080);
  r = parse_line_config(with("\"[::1]:9421\""), "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->observability.listen(), "[::1]:9421");
  r = parse_line_config(with("off"), "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_FALSE(r->observability.enabled);

  auto e = error_of(with("localhost:9420"));
  EXPECT_NE(e.find("line.yaml:3:11: observability: listen 'localhost:9420' does not name an IPv4 address"),
            std::string::npos)
      << e;
  e = error_of(with("127.0.0.1"));
  EXPECT_NE(e.find("listen '127.0.0.1' has no port"), std::string::npos) << e;
  e = error_of(with("127.0.0.1:70000"));
  EXPECT_NE(e.find("listen '127.0.0.1:70000' has no port 1..65535"), std::string::npos) << e;
  e = error_of(with("127.0.0.1:0"));
  EXPECT_NE(e.find("has no port 1..65535"), std::string::npos) << e;
  e = error_of(with("\"[::1:9420\""));
  EXPECT_NE(e.find("is not [IPv6]:PORT"), std::string::npos) << e;
  e = error_of(with("\"[nohost]:9420\""));
  EXPECT_NE(e.find("does not name an IPv6 address"), std::string::npos) << e;
  e = error_of(replace(kGood, "dds:\n", "observability:\n  listne: 127.0.0.1:9420\ndds:\n"));
  EXPECT_NE(e.find("line.yaml:3:3: unknown key 'listne' in observability"), std::string::npos) << e;
  e = error_of(replace(kGood, "dds:\n", "observability: 127.0.0.1:9420\ndds:\n"));
  EXPECT_NE(e.find("line.yaml:2:16: observability must be a mapping (key: value)"), std::string::npos) << e;
}

// status_publish: per_cycle unless the line says per_frame; anything else is refused with both.
TEST(LineConfig, StatusPublishIsPerCycleByDefaultPerFrameWhenSaidAndNothingElse) {
  const auto registry = ProfileRegistry::builtin();
  auto r = parse_line_config(kGood, "line.yaml", registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->status_publish, lb::profiles::StatusPublish::per_cycle);
  r = parse_line_config(replace(kGood, "line: test\n", "line: test\nstatus_publish: per_frame\n"), "line.yaml",
                        registry);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->status_publish, lb::profiles::StatusPublish::per_frame);
  const auto e = error_of(replace(kGood, "line: test\n", "line: test\nstatus_publish: per_sync\n"));
  EXPECT_NE(e.find("line.yaml:2:17: status_publish: 'per_sync' is neither per_cycle"), std::string::npos) << e;
  EXPECT_NE(e.find("nor per_frame"), std::string::npos) << e;
}
