// The integrator's tools, as the real executables run them: linebridge --check (no CAN, no DDS),
// linebridge-cli eds (a vendor's EDS/DCF against a profile), linebridge-cli candump (the raw
// frames of a virtual bus). Runs inside launch_scripts/netns-run.sh (private /dev/shm: --check
// must leave no Fast DDS shared-memory segment behind, which a participant would).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "can/candump_log.hpp"
#include "profiles/profile_registry.hpp"
#include "support/child_process.hpp"
#include "support/eds_text.hpp"
#include "support/run_command.hpp"
#include "support/spy_waits.hpp"

using lb::test::run_command;

namespace {

std::string tag() { return std::to_string(::getpid()); }

std::string write(const std::string& name, const std::string& text) {
  const auto path = ::testing::TempDir() + "/tools_" + tag() + "_" + name;
  std::ofstream(path) << text;
  return path;
}

std::size_t shm_entries() {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/dev/shm")) ++n;
  return n;
}

const std::string kDemo = std::string(LB_SOURCE_DIR) + "/config/lines/demo.yaml";

TEST(Check, DemoLineSummaryWithEveryTopicAndNoDdsNoCan) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  // With shared memory on, any participant would leave Fast DDS segments in /dev/shm.
  std::ifstream in(kDemo);
  std::stringstream demo;
  demo << in.rdbuf();
  std::string text = demo.str();
  text.replace(text.find("  localhost_only: true\n"), 23, "  localhost_only: true\n  shared_memory: true\n");
  const std::string weaving = "    interface: virtual:demo-weaving\n";
  text.replace(text.find(weaving), weaving.size(), weaving + "    realtime_priority: 30\n");
  const auto before = shm_entries();
  const auto r = run_command({LB_BIN_BRIDGE, "--check", write("demo.yaml", text)});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(shm_entries(), before) << "--check created Fast DDS shared-memory segments: it started a participant";
  for (const char* expected : {
           "line demo: 2 bus(es), 4 device(s)",
           "status samples per SYNC cycle (status_publish: per_cycle)",
           "bus extrusion on virtual:demo-extrusion: master, SYNC every 20 ms",
           "bus weaving on virtual:demo-weaving: master, SYNC every 20 ms, SDO timeout 1000 ms, loop at realtime "
           "priority 30 (SCHED_FIFO)\n",
           "saw1 node 3: saw cia420-4 3.1",
           "rt/demo/saw1/status",
           "linebridge_msgs::msg::dds_::SawStatus_",
           "bridge writes",
           "rt/demo/saw1/setpoint",
           "bridge reads",
           "rt/demo/bridge/diagnostics",
           "rq/demo/bridge/nmtRequest",
           "rr/demo/bridge/nmtReply",
           "reliable, transient-local, keep-last 1",
           "ok (0 warning(s))",
       }) {
    EXPECT_NE(r.output.find(expected), std::string::npos) << expected << "\n" << r.output;
  }
}

// The example line file the package ships (/etc/linebridge/line.yaml) passes --check as it is in
// the source tree: its profiles_dir (profiles, beside it) is there too.
TEST(Check, TheShippedLineFilePasses) {
  const auto shipped = std::string(LB_SOURCE_DIR) + "/packaging/etc/line.yaml";
  const auto r = run_command({LB_BIN_BRIDGE, "--check", shipped});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(shipped + ": ok"), std::string::npos) << r.output;
}

TEST(Check, ErrorsExitTwoWithTheirPlaceAndWarningsAreListed) {
  const auto bad = write("bad.yaml", "line: x\nbuses:\n  - {name: b, interface: 'virtual:x'}\ndevices:\n"
                                     "  - {name: saw1, bus: b, node_id: 300, profile: cia420-4, version: '3.1'}\n");
  auto r = run_command({LB_BIN_BRIDGE, "--check", bad});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(bad + ":5:"), std::string::npos) << r.output;

  // A socketcan interface this machine does not have is not an error of the file (the check may run
  // elsewhere) but is said; so are a recording outside the service's directory, a heartbeat timeout
  // without margin, and what a site profile sets that the contract keeps.
  const auto xml = write("site.xml", R"(<?xml version="1.0"?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"><profiles>
  <data_writer profile_name="rt/x/saw1/status"><qos><reliability><kind>BEST_EFFORT</kind></reliability></qos></data_writer>
  <data_writer profile_name="rt/x/saw1/statsu"><qos><deadline><period><sec>1</sec></period></deadline></qos></data_writer>
</profiles></dds>
)");
  const auto warn = write("warn.yaml",
                          "line: x\ndds: {profiles_file: '" + xml +
                              "'}\nbuses:\n"
                              "  - {name: b, interface: 'socketcan:lbcheck0', record: '" +
                              ::testing::TempDir() +
                              "/x.log'}\n"
                              "devices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1', "
                              "heartbeat_timeout_ms: 110, heartbeat_producer_ms: 100}\n");
  r = run_command({LB_BIN_BRIDGE, "--check", warn});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* expected : {"no network interface lbcheck0", "outside /var/lib/linebridge", "less than 1.5 x",
                               "rt/x/saw1/status: reliability is the DDS contract's",
                               "data_writer profile 'rt/x/saw1/statsu' names no topic", "ok (5 warning(s))"}) {
    EXPECT_NE(r.output.find(expected), std::string::npos) << expected << "\n" << r.output;
  }
  // A state_dir that cannot be used would start every device from zero after a restart: an error.
  const auto not_a_dir = write("not_a_dir", "");
  const auto stateless = write("state.yaml", "line: x\nstate_dir: '" + not_a_dir +
                                                 "'\nbuses:\n  - {name: b, interface: 'virtual:x'}\ndevices: []\n");
  r = run_command({LB_BIN_BRIDGE, "--check", stateless});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("error: state_dir " + not_a_dir + ": not a directory"), std::string::npos) << r.output;
  // Every state_dir problem is an error, each reported, with the machine's others: here a file in
  // the way, a directory this user may not create, and a missing recording, all three at once.
  const auto blocked = write("blocked.yaml", "line: x\nstate_dir: '" + not_a_dir +
                                                 "/sub'\nbuses:\n"
                                                 "  - {name: b, interface: 'log:/nonexistent/rec.log'}\ndevices: []\n");
  r = run_command({LB_BIN_BRIDGE, "--check", blocked});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("error: state_dir " + not_a_dir + "/sub: does not exist, and "), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("_not_a_dir is no directory to create it in"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error: bus b: cannot read the recording /nonexistent/rec.log"), std::string::npos)
      << "every error, not only the first\n"
      << r.output;
  // Missing but creatable: fine, start-up makes it; --check itself creates nothing.
  const auto creatable = ::testing::TempDir() + "/tools_" + tag() + "_state/a/b";
  const auto later = write("later.yaml", "line: x\nstate_dir: '" + creatable +
                                             "'\nbuses:\n  - {name: b, interface: 'virtual:x'}\ndevices: []\n");
  r = run_command({LB_BIN_BRIDGE, "--check", later});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(std::filesystem::exists(creatable)) << "--check created the state_dir";
  if (::geteuid() != 0) {  // root may write anywhere: the permission check says nothing then
    const auto locked = ::testing::TempDir() + "/tools_" + tag() + "_locked";
    std::filesystem::create_directory(locked);
    std::filesystem::permissions(locked, std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec);
    const auto ro = write("ro.yaml", "line: x\nstate_dir: '" + locked +
                                         "'\nbuses:\n  - {name: b, interface: 'virtual:x'}\ndevices: []\n");
    r = run_command({LB_BIN_BRIDGE, "--check", ro});
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find("error: state_dir " + locked + ": not writable"), std::string::npos) << r.output;
  }
  // A replay whose file is missing would stop start-up: an error.
  const auto replay = write("replay.yaml",
                            "line: x\nbuses:\n  - {name: b, interface: 'log:/nonexistent/rec.log'}\ndevices: []\n");
  r = run_command({LB_BIN_BRIDGE, "--check", replay});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("cannot read the recording /nonexistent/rec.log"), std::string::npos) << r.output;
}

// Every file the bridge, the CLI and the tools read goes through one bounded reader
// (base/bounded_file.hpp): a device that never ends (/dev/zero), a FIFO nobody writes (it would
// block) and a file far larger than any real one are refused with a clear error, exit 2, at once
// (each command is bounded at 30 s here; a hang or an abort fails the test).
TEST(BoundedFiles, DevZeroAFifoAndAnOversizeFileAreRefusedEverywhere) {
  const auto fifo = ::testing::TempDir() + "/tools_" + tag() + "_fifo";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto oversize = write("oversize", std::string(5 * 1024 * 1024, ';'));
  const auto refused = [](const lb::test::CommandResult& r) {
    return r.exit_code == 2 && (r.output.find("not a regular file") != std::string::npos ||
                                r.output.find("larger than") != std::string::npos);
  };
  for (const auto& bad : {std::string("/dev/zero"), fifo, oversize}) {
    // An EDS file (linebridge-cli eds aborted with std::bad_alloc on /dev/zero).
    auto r = run_command({LB_BIN_CLI, "eds", bad}, std::chrono::seconds(30));
    EXPECT_TRUE(refused(r)) << "eds " << bad << ": exit " << r.exit_code << "\n" << r.output;
    // The line file, given or from LINEBRIDGE_CONFIG, to each executable.
    r = run_command({LB_BIN_BRIDGE, "--check", bad}, std::chrono::seconds(30));
    EXPECT_TRUE(refused(r)) << "--check " << bad << ": exit " << r.exit_code << "\n" << r.output;
    r = run_command({"/usr/bin/env", "LINEBRIDGE_CONFIG=" + bad, LB_BIN_SIM, "--duration", "1"},
                    std::chrono::seconds(30));
    EXPECT_TRUE(refused(r)) << "linebridge-sim, LINEBRIDGE_CONFIG=" << bad << ": exit " << r.exit_code << "\n"
                            << r.output;
    r = run_command({LB_BIN_CLI, "--config", bad, "list"}, std::chrono::seconds(30));
    EXPECT_TRUE(refused(r)) << "linebridge-cli --config " << bad << ": exit " << r.exit_code << "\n" << r.output;
    // A site's DDS profiles file.
    const auto with_profiles = write("profiles-line.yaml",
                                     "line: x\ndds: {profiles_file: '" + bad +
                                         "'}\nbuses:\n  - {name: b, interface: 'virtual:x'}\ndevices: []\n");
    r = run_command({LB_BIN_BRIDGE, "--check", with_profiles}, std::chrono::seconds(30));
    EXPECT_TRUE(refused(r)) << "profiles_file " << bad << ": exit " << r.exit_code << "\n" << r.output;
    // The security files of a secured line.
    std::string security = "line: x\ndds:\n  security:\n";
    for (const char* key :
         {"identity_ca", "certificate", "private_key", "permissions_ca", "governance", "permissions"}) {
      security += std::string("    ") + key + ": '" + bad + "'\n";
    }
    const auto secured = write("secured-line.yaml",
                               security + "buses:\n  - {name: b, interface: 'virtual:x'}\ndevices: []\n");
    r = run_command({LB_BIN_SECURITY, "--config", secured, "check"}, std::chrono::seconds(30));
    EXPECT_TRUE(refused(r)) << "security files " << bad << ": exit " << r.exit_code << "\n" << r.output;
  }
  // A profile file in the line's profiles_dir.
  const auto dir = ::testing::TempDir() + "/tools_" + tag() + "_profiles";
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(oversize, dir + "/big.yaml", std::filesystem::copy_options::overwrite_existing);
  const auto with_dir = write("dir-line.yaml", "line: x\nprofiles_dir: '" + dir +
                                                   "'\nbuses:\n  - {name: b, interface: 'virtual:x'}\ndevices: []\n");
  const auto r = run_command({LB_BIN_BRIDGE, "--check", with_dir}, std::chrono::seconds(30));
  EXPECT_TRUE(refused(r)) << "a profile file: exit " << r.exit_code << "\n" << r.output;
  ::unlink(fifo.c_str());
}

// What a launch script says setup.sh installs ("mmdebstrap missing (launch_scripts/setup.sh
// --install-test installs it)"), setup.sh installs: its --list with the same options names it.
TEST(Scripts, WhatTheScriptsSaySetupInstallsItInstalls) {
  const std::regex claim(R"(([\w.+-]+) (?:is )?missing \(launch_scripts/setup\.sh((?: --[\w-]+)*) installs it\))");
  std::size_t claims = 0;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(LB_SOURCE_DIR) + "/launch_scripts")) {
    if (entry.path().extension() != ".sh") continue;
    std::ifstream in(entry.path());
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (std::sregex_iterator it(text.begin(), text.end(), claim), end; it != end; ++it) {
      ++claims;
      const std::string package = (*it)[1];
      std::vector<std::string> argv = {std::string(LB_SOURCE_DIR) + "/launch_scripts/setup.sh", "--list"};
      std::istringstream flags((*it)[2]);
      for (std::string f; flags >> f;) argv.push_back(f);
      const auto r = run_command(argv);
      ASSERT_EQ(r.exit_code, 0) << r.output;
      EXPECT_NE(("\n" + r.output).find("\n" + package + "\n"), std::string::npos)
          << entry.path().filename() << " says setup.sh" << (*it)[2] << " installs " << package << "; it installs:\n"
          << r.output;
    }
  }
  EXPECT_GE(claims, 2u) << "install-test.sh (mmdebstrap) and pki.sh (openssl) say so";
}

// `netns-run.sh --join PID COMMAND` runs COMMAND in the network (and mount) namespace of a line
// already running in its own, as a second terminal beside the demo does: there candump sees the
// line's virtual bus; from any other namespace (here the test's) it sees nothing of it.
TEST(NetnsJoin, ACommandJoinsARunningLinesNamespaceAndSeesItsBus) {
  const auto line = write("joined.yaml",
                          "line: joined\nbuses:\n  - {name: weaving, interface: 'virtual:joined-" + tag() +
                              "'}\ndevices:\n  - {name: saw1, bus: weaving, node_id: 3, profile: cia420-4, version: "
                              "'3.1', simulation: {heartbeat_period_ms: 50}}\n");
  // The simulator in a namespace of its own (no DDS: it has no participant), as demo.sh runs the line.
  lb::test::ChildProcess sim({"/usr/bin/unshare", "--net", "--mount", "--propagation", "private", "--", LB_BIN_SIM,
                              "--config", line, "--duration", "60"},
                             ::testing::TempDir() + "/joined_sim_" + tag() + ".log");
  ASSERT_TRUE(sim.started());
  const auto ns_of = [](const std::string& pid) {
    std::error_code ec;
    return std::filesystem::read_symlink("/proc/" + pid + "/ns/net", ec).string();
  };
  const auto pid = std::to_string(sim.pid());
  lb::test::eventually(std::chrono::seconds(30), [&] { return ns_of(pid) != ns_of("self"); });
  ASSERT_NE(ns_of(pid), ns_of("self")) << sim.log();
  const std::string netns_run = std::string(LB_SOURCE_DIR) + "/launch_scripts/netns-run.sh";
  auto r = run_command({netns_run, "--join", pid, LB_BIN_CLI, "--config", line, "candump", "weaving", "--count", "3",
                        "--duration", "30"});
  EXPECT_EQ(r.exit_code, 0) << r.output << sim.log();
  EXPECT_NE(r.output.find(" weaving 703#"), std::string::npos) << "joined: the line's heartbeats\n"
                                                               << r.output << sim.log();
  r = run_command({LB_BIN_CLI, "--config", line, "candump", "weaving", "--count", "1", "--duration", "2"});
  EXPECT_EQ(r.output.find(" weaving 703#"), std::string::npos) << "not joined: nothing of that bus\n" << r.output;
  r = run_command({netns_run, "--join", "no-such-process-" + tag(), "true"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("no process named"), std::string::npos) << r.output;
}

class Eds : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto registry = lb::profiles::ProfileRegistry::builtin();
    eds_ = lb::test::eds_of(*registry.find("cia420-4", "3.1"), 0x04200004);
    line_ = write("eds-line.yaml", "line: x\nbuses:\n  - {name: b, interface: 'virtual:x'}\ndevices:\n"
                                   "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n");
  }
  lb::test::CommandResult eds(const std::string& text, std::vector<std::string> extra = {"--device", "saw1"}) {
    std::vector<std::string> argv = {LB_BIN_CLI, "--config", line_, "eds", write("device.eds", text)};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return run_command(argv);
  }
  std::string eds_;
  std::string line_;
};

TEST_F(Eds, TheProfilesOwnDeviceFitsAndGivesItsIdentity) {
  const auto r = eds(eds_);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* expected : {"against profile cia420-4@3.1", "node-ID 3", "identity:", "device_type: 0x000001A4",
                               "vendor_id: 0x4C420000", "product_code: 0x04200004", "revision: 0x00010000"}) {
    EXPECT_NE(r.output.find(expected), std::string::npos) << expected << "\n" << r.output;
  }
  EXPECT_EQ(r.output.find("pdos:"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("serial_number"), std::string::npos) << "an EDS describes a model, not one device";
}

TEST_F(Eds, WhatDoesNotFitTheProfileIsNamed) {
  auto r = eds(lb::test::eds_set(eds_, "1000", "DefaultValue", "0x000001A5"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("profile number 421 in the file, 420 in cia420-4@3.1"), std::string::npos) << r.output;

  r = eds(lb::test::eds_set(eds_, "6002", "DataType", "0x0006"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("6002h sub 0 product_length_set_value: data type UNSIGNED16"), std::string::npos) << r.output;

  r = eds(lb::test::eds_set(eds_, "6020", "AccessType", "ro"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("6020h sub 0 control_word: the profile writes it, the file says access 'ro'"),
            std::string::npos)
      << r.output;

  r = eds(lb::test::eds_set(eds_, "6007", "PDOMapping", "0"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("the profile maps it in tpdo2, the file says PDOMapping=0"), std::string::npos) << r.output;

  std::string missing = eds_;
  missing.replace(missing.find("[6030]"), 6, "[7030]");
  r = eds(missing);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("6030h sub 0 status_word: not in the file"), std::string::npos) << r.output;
}

TEST_F(Eds, TheDevicesOwnPdoDefaultsBecomeOverrides) {
  auto text = lb::test::eds_set(eds_, "1801sub2", "DefaultValue", "254");
  text = lb::test::eds_set(text, "1801sub5", "DefaultValue", "100");
  text = lb::test::eds_set(text, "1A01sub1", "DefaultValue", "0x60070020");
  text = lb::test::eds_set(text, "1A01sub2", "DefaultValue", "0x60010020");
  auto r = eds(text);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("tpdo2: {transmission_type: 254, event_timer_ms: 100, mapping: [0x60070020, 0x60010020]}"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("tpdo2 mapping: the device fixes it"), std::string::npos) << r.output;

  // A mapping of an object the profile lacks is no override the bridge could use.
  r = eds(lb::test::eds_set(eds_, "1A01sub1", "DefaultValue", "0x21100010"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("mapping: ["), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("maps 2110h sub 0 by default, which profile cia420-4@3.1 does not define"), std::string::npos)
      << r.output;
}

TEST_F(Eds, ADcfGivesItsNodeIdAndSerialNumber) {
  auto dcf = eds_ + "[DeviceComissioning]\nNodeID=0x07\nNodeName=saw1\nBaudrate=500\n";
  dcf = lb::test::eds_add(dcf, "1018sub4", "ParameterValue", "0x51000007");
  dcf = lb::test::eds_add(dcf, "1800sub1", "ParameterValue", "$NODEID+0x190");
  const auto r = eds(dcf, {"--profile", "cia420-4", "--profile-version", "3.1"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("node-ID 7"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("serial_number: 0x51000007"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("tpdo1: {cob_id: 0x00000197}"), std::string::npos) << r.output;
}

TEST_F(Eds, FilesThatAreNoEdsAreRefused) {
  auto r = eds("[FileInfo]\nFileName=x\n");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("no [DeviceInfo] section"), std::string::npos) << r.output;
  r = eds("[DeviceInfo]\nVendorNumber=0x12\nthis line has no equals sign\n");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("device.eds:3: expected key=value"), std::string::npos) << r.output;
  r = eds(lb::test::eds_set(eds_, "1000", "DefaultValue", "0x1G4"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("'0x1G4' is not a number"), std::string::npos) << r.output;
  r = eds(eds_, {});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("profiles of this device type:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" cia420-4@3.1"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("cia414"), std::string::npos) << "a CiA 414 profile for a device type of 420: " << r.output;
  // Read with the line file's bounds: /dev/zero is refused at once (it grew to gigabytes and
  // aborted with std::bad_alloc before).
  r = run_command({LB_BIN_CLI, "eds", "/dev/zero"}, std::chrono::seconds(20));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/dev/zero: EDS/DCF file: not a regular file"), std::string::npos) << r.output;
}

// A virtual bus, watched as candump watches a CAN interface: the simulator's boot-up and
// heartbeats appear with what they are, in the log format canplayer replays; nothing is sent.
TEST(Candump, WatchesAVirtualBusOfTheLine) {
  const auto bus = "virtual:candump-" + tag();
  const auto recording = write("old.log", "(1700000000.000000) can0 183#00\n");
  const auto line = write("candump.yaml", "line: x\nbuses:\n  - {name: weaving, interface: '" + bus +
                                              "'}\n  - {name: old, interface: "
                                              "'log:" +
                                              recording +
                                              "'}\ndevices:\n  - {name: saw1, bus: weaving, node_id: 3, profile: "
                                              "cia420-4, version: '3.1', simulation: {heartbeat_period_ms: 50}}\n");
  lb::test::ChildProcess sim({LB_BIN_SIM, "--config", line, "--duration", "20"},
                             ::testing::TempDir() + "/candump_sim_" + tag() + ".log");
  // The simulator is on the bus (its first heartbeat at a passive member) before candump joins.
  lb::test::BusSpy spy(bus);
  ASSERT_FALSE(spy.wait_count(0x703, 1, std::chrono::seconds(20)).empty()) << sim.log();
  auto r = run_command({LB_BIN_CLI, "--config", line, "candump", "weaving", "--count", "3", "--duration", "10"});
  EXPECT_EQ(r.exit_code, 0) << r.output << sim.log();
  EXPECT_NE(r.output.find(" weaving 703#7F"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("heartbeat node 3: pre-operational"), std::string::npos) << r.output;

  r = run_command({LB_BIN_CLI, "--config", line, "candump", "weaving", "--count", "2", "--log"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  std::istringstream lines(r.output);
  int frames = 0;
  for (std::string l; std::getline(lines, l);) {
    auto rec = lb::can::parse_log_line(l);
    ASSERT_TRUE(rec && *rec) << "not a candump -l line: " << l;
    EXPECT_EQ((*rec)->interface, "weaving");
    ++frames;
  }
  EXPECT_EQ(frames, 2);

  r = run_command({LB_BIN_CLI, "--config", line, "candump", "old"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("replays a recording"), std::string::npos) << r.output;
  r = run_command({LB_BIN_CLI, "--config", line, "candump", "nope"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("buses: weaving, old"), std::string::npos) << r.output;
}

}  // namespace
