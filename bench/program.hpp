#pragma once
// What every bench program shares: its name in messages and exit codes, the options that describe
// the bench line (--prefix, --buses, --devices, --domain) and the rendezvous with bench.sh (--ready,
// --go, --stop/--linger), each spelled, defaulted and checked once, so that bench.sh can pass the
// same words to every program and a program cannot drift from the others.

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "names.hpp"
#include "rendezvous.hpp"

namespace lb::bench {

class Program {
 public:
  Program(std::string name, const std::string& what) : cli(name + ": " + what), name_(std::move(name)) {}

  CLI::App cli;  // for the options only this program has

  std::string prefix = "bench";
  int buses = 1;
  int devices = 30;
  int domain = 0;
  std::string ready_file, go_file, stop_file;
  double linger_s = 2;

  const std::string& name() const { return name_; }

  void add_prefix() { cli.add_option("--prefix", prefix, "virtual bus names: <prefix>-<i>")->capture_default_str(); }
  void add_buses() { cli.add_option("--buses", buses)->check(CLI::Range(1, 64))->capture_default_str(); }
  void add_devices(const char* help) {
    cli.add_option("--devices", devices, help)->check(CLI::Range(1, kMaxDevicesPerBus))->capture_default_str();
  }
  void add_domain(const char* help = "") {
    cli.add_option("--domain", domain, help)->check(CLI::Range(0, 232))->capture_default_str();
  }
  void add_ready(const char* when) { cli.add_option("--ready", ready_file, std::string("created once ") + when); }
  void add_go(const char* what) { cli.add_option("--go", go_file, std::string(what) + " once this file exists"); }
  void add_stop(const char* after) {
    cli.add_option("--stop", stop_file, std::string("after ") + after + ", stay until this file exists (or --linger)");
    cli.add_option("--linger", linger_s, std::string("at most this long after ") + after + ", seconds")
        ->capture_default_str();
  }

  // The exit code when the command line does not parse (or asks for --help); nothing when it does.
  std::optional<int> parse(int argc, char** argv) {
    try {
      cli.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      return cli.exit(e);
    }
    return std::nullopt;
  }

  // "bench-x: why" on stderr; the exit code of a failed run, for `return program.fail(...)`.
  int fail(const std::string& why) const {
    std::fprintf(stderr, "%s: %s\n", name_.c_str(), why.c_str());
    return 1;
  }

  // bench.sh's side of the rendezvous: this process is ready; everyone is (false: no go in time).
  void ready() const { signal_file(ready_file); }
  bool go() const {
    if (await_file(go_file, std::chrono::seconds(300))) return true;
    fail("no go within 300 s");
    return false;
  }
  // After the work, until bench.sh says stop or --linger has passed (a process that hosts the
  // virtual buses' hubs would otherwise lose the frames they still forward).
  void linger() const {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(linger_s);
    while (!file_exists(stop_file) && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }

 private:
  std::string name_;
};

}  // namespace lb::bench
