// Argument handling and exit codes of every executable (README "Exit codes"): the real binaries,
// run to their end. Every case here must be refused before anything starts; the test still runs
// inside launch_scripts/netns-run.sh so that a regression could not reach a network.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <string>
#include <vector>

#include "app/cli_exit.hpp"
#include "support/run_command.hpp"

using lb::test::run_command;

namespace {

const std::vector<std::string> kExecutables = {LB_BIN_BRIDGE, LB_BIN_SIM, LB_BIN_CLI, LB_BIN_SECURITY};

std::string write_file(const std::string& name, const std::string& text) {
  const auto path = ::testing::TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string line_with_interface(const std::string& name, const std::string& interface) {
  return write_file(name, "line: args\nbuses:\n  - name: b\n    interface: '" + interface +
                              "'\ndevices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n");
}

TEST(Arguments, UnknownOptionIsUsageErrorEverywhere) {
  for (const auto& exe : kExecutables) {
    std::vector<std::string> argv = {exe, "--no-such-option"};
    if (exe == LB_BIN_CLI) argv.push_back("list");
    if (exe == LB_BIN_SECURITY) argv.push_back("governance");
    const auto r = run_command(argv);
    EXPECT_EQ(r.exit_code, 2) << exe << ": " << r.output;
    EXPECT_NE(r.output.find("no-such-option"), std::string::npos) << exe << ": " << r.output;
  }
  // CLI11's own codes were 106 (a value that is no number) and 109 (an extra argument).
  EXPECT_EQ(run_command({LB_BIN_CLI, "echo"}).exit_code, 2);
  EXPECT_EQ(run_command({LB_BIN_CLI, "no-such-command"}).exit_code, 2);
  EXPECT_EQ(run_command({LB_BIN_BRIDGE, "--duration", "ten"}).exit_code, 2);
  EXPECT_EQ(run_command({LB_BIN_SIM, "extra"}).exit_code, 2);
}

TEST(Arguments, VersionAndHelpEverywhere) {
  const std::vector<std::string> names = {"linebridge ", "linebridge-sim ", "linebridge-cli ", "linebridge-security "};
  for (std::size_t i = 0; i < kExecutables.size(); ++i) {
    const auto v = run_command({kExecutables[i], "--version"});
    EXPECT_EQ(v.exit_code, 0) << v.output;
    EXPECT_EQ(v.output.rfind(names[i] + "0.", 0), 0U) << v.output;
    EXPECT_NE(v.output.find("Fast DDS 2."), std::string::npos) << v.output;
    const auto h = run_command({kExecutables[i], "--help"});
    EXPECT_EQ(h.exit_code, 0) << h.output;
    EXPECT_NE(h.output.find("Exit codes"), std::string::npos) << h.output;
  }
}

// LINEBRIDGE_CONFIG names the line file for the bridge, the simulator, the CLI and the security tool alike (the
// bridge and the simulator served the demo line without a word); --config wins over it; the
// bridge and the simulator log which line they serve.
TEST(Arguments, LineFileFromTheEnvironmentForEveryExecutable) {
  const auto line = write_file("envline.yaml",
                               "line: envline\nbuses:\n  - {name: b, interface: 'virtual:envline-" +
                                   std::to_string(::getpid()) +
                                   "'}\ndevices:\n"
                                   "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n");
  const std::string env = "LINEBRIDGE_CONFIG=" + line;
  auto r = run_command({"/usr/bin/env", env, LB_BIN_SIM, "--duration", "0.5"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("playing line file " + line), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("of line envline"), std::string::npos) << r.output;
  r = run_command({"/usr/bin/env", env, LB_BIN_BRIDGE, "--duration", "1"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("serving line file " + line), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("line envline: 1 bus(es), 1 device(s)"), std::string::npos) << r.output;
  r = run_command({"/usr/bin/env", env, LB_BIN_CLI, "list"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("device saw1 on b node 3"), std::string::npos) << r.output;
  // The bridge's grants name the line's topics: rt/envline/..., not the demo line's.
  r = run_command(
      {"/usr/bin/env", env, LB_BIN_SECURITY, "permissions", "--role", "bridge", "--subject", "CN=bridge,O=Plant"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("rt/envline/*"), std::string::npos) << r.output;
  // --config wins over the environment.
  r = run_command(
      {"/usr/bin/env", "LINEBRIDGE_CONFIG=/nonexistent/line.yaml", LB_BIN_SIM, "--config", line, "--duration", "0.5"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("playing line file " + line), std::string::npos) << r.output;
  // Neither: the built-in demo line, and the log says so.
  r = run_command({"/usr/bin/env", "-u", "LINEBRIDGE_CONFIG", LB_BIN_SIM, "--duration", "0.5"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("playing the built-in demo line (demo.yaml"), std::string::npos) << r.output;
}

// Every code an executable leaves with is in its --help, each with what it means: the table the
// footer is made from is the one the code returns from (cli_exit.hpp, arguments.hpp).
TEST(Arguments, HelpListsEveryExitCode) {
  const auto listed = [](const std::string& help, int code) {
    const auto from = help.find("Exit codes:");
    return from != std::string::npos && (help.find(" " + std::to_string(code) + " ", from) != std::string::npos);
  };
  const auto cli = run_command({LB_BIN_CLI, "--help"});
  ASSERT_EQ(cli.exit_code, 0) << cli.output;
  for (const int code : {lb::app::kExitOk, lb::app::kExitRefused, lb::app::kExitUsage, lb::app::kExitNoAnswer,
                         lb::app::kExitBridgeRestarted}) {
    EXPECT_TRUE(listed(cli.output, code)) << "linebridge-cli --help lacks exit code " << code << ":\n" << cli.output;
  }
  for (const auto& c : lb::app::kCliExitCodes) {
    EXPECT_NE(cli.output.find(std::string(c.meaning.substr(0, 20))), std::string::npos) << c.code << ": " << cli.output;
  }
  const auto bridge = run_command({LB_BIN_BRIDGE, "--help"});
  for (const int code : {lb::app::kExitOk, lb::app::kExitFailure, lb::app::kExitUsage, lb::app::kExitLoopFailed}) {
    EXPECT_TRUE(listed(bridge.output, code)) << "linebridge --help lacks exit code " << code << ":\n" << bridge.output;
  }
  // The bridge, the simulator and the security tool send no request: no exit code of theirs means
  // a refusal (their --help said "a request the bridge refused"), and each lists its own.
  const auto sim = run_command({LB_BIN_SIM, "--help"});
  const auto security = run_command({LB_BIN_SECURITY, "--help"});
  EXPECT_TRUE(listed(sim.output, lb::app::kExitFailure)) << sim.output;
  EXPECT_FALSE(listed(security.output, lb::app::kExitFailure)) << "linebridge-security never leaves with 1\n"
                                                               << security.output;
  for (const auto* help : {&bridge, &sim, &security}) {
    const auto footer = help->output.find("Exit codes:");
    ASSERT_NE(footer, std::string::npos) << help->output;
    EXPECT_EQ(help->output.find("refused", footer), std::string::npos) << help->output;
  }
  EXPECT_NE(bridge.output.find("1 start-up failure (a bus, the channel or the DDS participant cannot be opened)"),
            std::string::npos)
      << bridge.output;
  EXPECT_NE(sim.output.find("1 a bus cannot be opened or a device cannot be played"), std::string::npos) << sim.output;
}

TEST(Arguments, DurationsMustBeFiniteAndBounded) {
  for (const auto& exe : {std::string(LB_BIN_BRIDGE), std::string(LB_BIN_SIM)}) {
    for (const char* bad : {"-5", "nan", "inf", "1e30", "-0.001", "31536001"}) {
      const auto r = run_command({exe, "--duration", bad});
      EXPECT_EQ(r.exit_code, 2) << exe << " --duration " << bad << ": " << r.output;
      EXPECT_NE(r.output.find("duration"), std::string::npos) << r.output;
    }
  }
  for (const char* bad : {"-5", "nan", "1e30"}) {
    EXPECT_EQ(run_command({LB_BIN_CLI, "echo", "saw1", "--duration", bad}).exit_code, 2) << bad;
    EXPECT_EQ(run_command({LB_BIN_CLI, "candump", "extrusion", "--duration", bad}).exit_code, 2) << bad;
  }
  for (const char* bad : {"0", "-1", "nan", "inf"}) {
    EXPECT_EQ(run_command({LB_BIN_CLI, "echo", "saw1", "--rate", bad}).exit_code, 2) << bad;
    EXPECT_EQ(run_command({LB_BIN_CLI, "nmt", "saw1", "start", "--timeout", bad}).exit_code, 2) << bad;
    EXPECT_EQ(run_command({LB_BIN_CLI, "set", "saw1", "--timeout", bad}).exit_code, 2) << bad;
  }
}

TEST(Arguments, MistypedLogLevelIsRefused) {
  for (const auto& exe : {std::string(LB_BIN_BRIDGE), std::string(LB_BIN_SIM)}) {
    const auto r = run_command({exe, "--log-level", "verbose"});
    EXPECT_EQ(r.exit_code, 2) << exe << ": " << r.output;
    EXPECT_NE(r.output.find("verbose"), std::string::npos) << r.output;
  }
}

TEST(Arguments, EmptyConfigPathIsRefusedNotTheDemoLine) {
  for (const auto& exe : kExecutables) {
    std::vector<std::string> argv = {exe, "--config", ""};
    if (exe == LB_BIN_CLI) argv.push_back("list");
    if (exe == LB_BIN_SECURITY) argv.push_back("governance");
    const auto r = run_command(argv);
    EXPECT_EQ(r.exit_code, 2) << exe << ": " << r.output;
    EXPECT_NE(r.output.find("empty"), std::string::npos) << exe << ": " << r.output;
  }
  EXPECT_EQ(run_command({LB_BIN_BRIDGE, "--check", ""}).exit_code, 2);
}

// A malformed interface is a configuration error with its place in the file, in every executable
// and in --check, exit 2 (the unit does not restart on 2), never a start-up failure (exit 1).
TEST(Arguments, MalformedInterfacesAreConfigurationErrorsWithTheirPlace) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"socketcan:", "empty"},
      {"virtual:", "empty"},
      {"socketcan:" + std::string(16, 'c'), "interface name"},
      {"socketcan:can/0", "interface name"},
      {"virtual:" + std::string(100000, 'v'), "bus name"},
      {"virtual:a b", "bus name"},
      {"can0", "unknown scheme"},
  };
  int n = 0;
  for (const auto& [interface, says] : cases) {
    const auto path = line_with_interface("iface_" + std::to_string(++n) + ".yaml", interface);
    for (const auto& argv : std::vector<std::vector<std::string>>{{LB_BIN_BRIDGE, "--config", path},
                                                                  {LB_BIN_BRIDGE, "--check", path},
                                                                  {LB_BIN_SIM, "--config", path},
                                                                  {LB_BIN_CLI, "--config", path, "list"}}) {
      const auto r = run_command(argv);
      EXPECT_EQ(r.exit_code, 2) << argv[0] << " " << interface.substr(0, 40) << ": " << r.output;
      EXPECT_NE(r.output.find(path + ":4:16:"), std::string::npos)
          << interface.substr(0, 40) << ": " << r.output.substr(0, 400);
      EXPECT_NE(r.output.find(says), std::string::npos) << r.output.substr(0, 400);
      EXPECT_LT(r.output.size(), 2000U) << "the message repeats a huge name";
    }
  }
}

}  // namespace
