#pragma once
// What every bench program shares: its name in messages and exit codes, the options that describe
// the bench line (--prefix, --buses, --devices, --domain) and the rendezvous with bench.sh (--ready,
// --go, --stop/--linger) and DDS Security (--pki, --identity), each spelled, defaulted and checked once, so that
// bench.sh can pass the same words to every program and a program cannot drift from the others.

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "latencies.hpp"
#include "names.hpp"
#include "rendezvous.hpp"

namespace lb::bench {

// --pki DIR --identity NAME: a participant secured with an identity launch_scripts/pki.sh issued.
inline void add_security_options(CLI::App& cli, std::string& pki, std::string& identity) {
  auto* p = cli.add_option("--pki", pki,
                           "DDS Security: the PKI folder launch_scripts/pki.sh made (default: unsecured)");
  cli.add_option("--identity", identity, "DDS Security: the identity's folder in the PKI")->needs(p);
}

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
  double rate = 3000;           // --rate: frames (samples) per second, as bench.sh offers them
  std::uint64_t count = 10000;  // --count: how many
  std::string latencies_file;   // --out
  std::string pki, identity;    // --pki/--identity; the participant they make: security_option.hpp

  const std::string& name() const { return name_; }

  void add_prefix() { cli.add_option("--prefix", prefix, "virtual bus names: <prefix>-<i>")->capture_default_str(); }
  void add_buses() { cli.add_option("--buses", buses)->check(CLI::Range(1, 64))->capture_default_str(); }
  void add_devices(const char* help) {
    cli.add_option("--devices", devices, help)->check(CLI::Range(1, kMaxDevicesPerBus))->capture_default_str();
  }
  void add_domain(const char* help = "") {
    cli.add_option("--domain", domain, help)->check(CLI::Range(0, 232))->capture_default_str();
  }
  // --out FILE: every latency a measuring program took, so that a run can be analysed again.
  void add_out() { cli.add_option("--out", latencies_file, "write every latency (ns), one per line"); }
  void save_latencies(const std::vector<std::int64_t>& ns) const {
    if (!latencies_file.empty()) write_latencies(latencies_file, ns);
  }

  // The offered load: bench-inject's frames and bench-status-pub's samples follow the same words.
  void add_load(const char* rate_help, const char* count_help) {
    cli.add_option("--rate", rate, rate_help)->check(CLI::PositiveNumber)->capture_default_str();
    cli.add_option("--count", count, count_help)->capture_default_str();
  }
  void add_ready(const char* when) { cli.add_option("--ready", ready_file, std::string("created once ") + when); }
  void add_go(const char* what) { cli.add_option("--go", go_file, std::string(what) + " once this file exists"); }
  void add_stop(const char* after) {
    cli.add_option("--stop", stop_file, std::string("after ") + after + ", stay until this file exists (or --linger)");
    cli.add_option("--linger", linger_s, std::string("at most this long after ") + after + ", seconds")
        ->capture_default_str();
  }

  // DDS Security for the program's participants: an identity launch_scripts/pki.sh issued.
  void add_security() { add_security_options(cli, pki, identity); }

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
