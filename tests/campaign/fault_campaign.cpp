// The fault campaign of issue 40 (point 6): a line of every registered device type (saw 3.1 and
// 1.0, puller, corrugator, winder on one bus; the feeder box on a second), each device a simulator
// process of its own, served by the real bridge, runs for --minutes while a schedule drawn from
// --seed injects faults (fault_schedule.hpp) and an operator per device keeps setting and stopping
// (campaign_operator.hpp); the safety table's invariants are checked from the bus and the DDS
// answers every few seconds and once at the end (campaign_judge.hpp). It prints the seed, the
// faults by kind, the stops and their times to the bus, and every violation with its frames
// (campaign_report.hpp). Exit 0: no violation; 1: violations (or a bridge process that ended by
// itself); 2: the campaign could not run its course (the line never came up, the recorder lost
// frames, a signal ended it early without a violation).
//
// Run it through launch_scripts/fault-campaign.sh (a private network namespace: every DDS
// participant must run in one); a short run is the ctest test integration_fault_campaign_short.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "app/run_until_signal.hpp"
#include "campaign/campaign_judge.hpp"
#include "campaign/campaign_line.hpp"
#include "campaign/campaign_operator.hpp"
#include "campaign/campaign_report.hpp"
#include "campaign/fault_schedule.hpp"
#include "support/safety_device.hpp"

namespace campaign = lb::test::campaign;
namespace safety = lb::test::safety;

namespace {

// The table's columns under names of their own (the two saws are both "saw1" there).
std::vector<campaign::CampaignDevice> the_line() {
  const auto named = [](safety::SafetyDevice d, std::string name) {
    d.name = std::move(name);
    return d;
  };
  return {{named(safety::saw31(), "saw31"), "extrusion"},
          {named(safety::saw10(), "saw10"), "extrusion"},
          {safety::puller(), "extrusion"},
          {safety::corrugator(), "extrusion"},
          {safety::winder(), "extrusion"},
          {safety::feeder(), "weaving"}};
}

// The machine's 1-minute load average (stop times are judged in milliseconds on a shared machine).
double load_average() {
  std::ifstream in("/proc/loadavg");
  double load = 0;
  in >> load;
  return load;
}

void say(const std::string& text) {
  std::fputs(text.c_str(), stdout);
  std::fflush(stdout);
}

// The judge, every few seconds, on its own thread: new violations are printed as they are found.
class Watcher {
 public:
  Watcher(campaign::CampaignJudge& judge, campaign::CampaignLine& line, std::chrono::seconds every)
      : thread_([this, &judge, &line, every] {
          std::unique_lock lock(m_);
          while (!cv_.wait_for(lock, every, [this] { return stop_; })) {
            max_load_ = std::max(max_load_.load(), load_average());
            lock.unlock();
            const auto found = judge.interim();
            for (const auto& f : found) {
              const auto& d = line.devices()[f.device].device;
              say(fmt::format("[{}] violation {} {}: {}\n", at(line, f.violation.at_ns), f.violation.invariant, d.name,
                              f.violation.text));
            }
            lock.lock();
          }
        }) {}
  ~Watcher() {
    {
      std::lock_guard lock(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  Watcher(const Watcher&) = delete;
  Watcher& operator=(const Watcher&) = delete;
  double max_load() const { return max_load_; }
  static std::string at(const campaign::CampaignLine& line, std::int64_t ns) {
    return fmt::format("+{:.3f} s", static_cast<double>(ns - line.t0()) / 1e9);
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::atomic<double> max_load_{0};
  std::thread thread_;
};

// SIGINT / SIGTERM end the campaign early, cleanly: every fault under way is undone (devices
// powered and resumed, the bridge started, clients resumed), the operators stop, and the verdict
// is given on what ran. Signals are blocked in every thread and taken by a thread of their own
// (app/run_until_signal.hpp, as the bridge, the simulator and the CLI do: the processes started
// here inherit the blocked mask, and block and wait for those signals themselves anyway).
class Interrupt {
 public:
  Interrupt() {
    lb::app::block_stop_signals();
    thread_ = std::thread([this] {
      const int sig = lb::app::run_until_signal(std::chrono::milliseconds(0));
      std::lock_guard lock(m_);
      if (!closing_) signal_ = sig;
      cv_.notify_all();
    });
  }
  ~Interrupt() {
    {
      std::lock_guard lock(m_);
      closing_ = true;
    }
    lb::app::request_stop();  // SIGUSR1: the thread's wait ends
    thread_.join();
  }
  Interrupt(const Interrupt&) = delete;
  Interrupt& operator=(const Interrupt&) = delete;

  // Until `when`; false at once when a signal came.
  bool wait_until(std::chrono::steady_clock::time_point when) {
    std::unique_lock lock(m_);
    return !cv_.wait_until(lock, when, [this] { return signal_ != 0; });
  }
  int signal() {
    std::lock_guard lock(m_);
    return signal_;
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  int signal_ = 0;
  bool closing_ = false;
  std::thread thread_;
};

// One step of the schedule, carried out on the line. False when it could not be (no DDS process
// to kill: the bridge was down).
bool carry_out(campaign::CampaignLine& line, const campaign::FaultSchedule& schedule, const campaign::FaultStep& step) {
  const auto& f = schedule.faults[step.fault];
  switch (f.kind) {
    case campaign::FaultKind::power_cycle:
      step.step == 0 ? line.power_off(f.target) : line.power_on(f.target);
      return true;
    case campaign::FaultKind::device_stall:
      step.step == 0 ? line.stall_device(f.target) : line.resume_device(f.target);
      return true;
    case campaign::FaultKind::kill_bus_process:
      step.step == 0 ? line.kill_bus_process() : line.start_bus_process();
      return true;
    case campaign::FaultKind::kill_dds_process: return line.kill_dds_process();
    case campaign::FaultKind::bridge_restart: line.restart_bridge(); return true;
    case campaign::FaultKind::spoofed_heartbeats:
    case campaign::FaultKind::spoofed_sdo: line.spoof(line.devices()[f.target].bus, *step.frame); return true;
    case campaign::FaultKind::spoofed_syncs: line.spoof(line.buses()[f.target], *step.frame); return true;
    case campaign::FaultKind::stalled_client:
      step.step == 0 ? line.stall_client(f.target) : line.resume_client(f.target);
      return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  Interrupt interrupt;  // first: every thread started after it has the stop signals blocked
  CLI::App cli{"fault-campaign: a line of every device type under a seeded schedule of faults, judged from the bus"};
  double minutes = 30;
  std::uint64_t seed = 0;
  double mean_gap_s = 5;
  int judge_every_s = 10;
  std::string dir;
  cli.add_option("--minutes", minutes, "how long the line runs (faults stop 20 s before the end)")
      ->check(CLI::Range(1.0, 24 * 60.0))
      ->capture_default_str();
  cli.add_option("--seed", seed, "the schedule's seed (default: drawn, and printed); the same seed replays a run");
  cli.add_option("--mean-gap-s", mean_gap_s, "mean time between two faults' beginnings")
      ->check(CLI::Range(0.5, 600.0))
      ->capture_default_str();
  cli.add_option("--judge-every-s", judge_every_s, "the invariants are checked this often while it runs")
      ->check(CLI::Range(1, 600))
      ->capture_default_str();
  cli.add_option("--dir", dir, "the line's files and every process's log (default: /tmp/fault-campaign-PID)");
  CLI11_PARSE(cli, argc, argv);
  if (seed == 0) seed = std::random_device{}() | (std::uint64_t{std::random_device{}()} << 32);
  if (dir.empty()) dir = "/tmp/fault-campaign-" + std::to_string(::getpid());
  const auto duration_ms = static_cast<std::int64_t>(minutes * 60'000);

  say(fmt::format("fault campaign: seed {}, {} min, mean gap between faults {} s; logs in {}\n", seed, minutes,
                  mean_gap_s, dir));
  say(fmt::format("  replay: launch_scripts/fault-campaign.sh --minutes {} --seed {} --mean-gap-s {}\n", minutes, seed,
                  mean_gap_s));
  say("  bus-off: not injected (the virtual bus cannot emulate it: it carries every frame whatever a member "
      "reports)\n");

  campaign::CampaignLine line(the_line(), {dir, 90, 500});
  std::vector<std::unique_ptr<campaign::CampaignOperator>> operators;
  try {
    line.start();
    for (std::size_t i = 0; i < line.devices().size(); ++i) {
      operators.push_back(
          std::make_unique<campaign::CampaignOperator>(line, i,
                                                       campaign::plan_operator(seed, i, duration_ms - 12'000)));
      if (!operators.back()->warm())
        throw std::runtime_error("the operator's panel of " + line.devices()[i].device.name +
                                 " never reached the bridge\n" + line.logs());
    }
  } catch (const std::exception& e) {
    say(fmt::format("the campaign could not start: {}\n", e.what()));
    return 2;
  }
  std::string devices;
  for (const auto& d : line.devices())
    devices += fmt::format(" {} ({} node {} on {})", d.device.name, d.device.column, d.device.node, d.bus);
  say("  line up:" + devices + "\n");

  campaign::ScheduleTargets targets;
  for (const auto& d : line.devices()) {
    targets.devices.push_back({d.device.name, d.device.node, d.bus == "extrusion" ? std::size_t{0} : std::size_t{1}});
  }
  targets.buses = line.buses();
  targets.clients = line.clients();
  const auto schedule = campaign::FaultSchedule::draw(seed, targets, duration_ms,
                                                      static_cast<std::int64_t>(mean_gap_s * 1000));
  say(fmt::format("  {} faults scheduled\n", schedule.faults.size()));

  campaign::CampaignJudge judge(line, operators);
  std::vector<campaign::Executed> executed;
  std::size_t ended_by_itself = 0;
  const double load_at_start = load_average();
  double max_load = load_at_start;
  const auto start_ns = lb::test::bus_now_ns();
  const auto start = std::chrono::steady_clock::now();
  for (auto& op : operators) op->start(start_ns);
  {
    Watcher watcher(judge, line, std::chrono::seconds(judge_every_s));
    bool bus_process_down = false;  // killed by the campaign, not started again yet
    for (std::size_t k = 0; k < schedule.steps.size(); ++k) {
      const auto& step = schedule.steps[k];
      if (!interrupt.wait_until(start + std::chrono::milliseconds(step.at_ms))) {
        // Ended early: every fault under way is undone now (its ending steps), nothing new begins.
        std::vector<bool> begun(schedule.faults.size(), false);
        for (const auto& e : executed) begun[e.fault] = begun[e.fault] || e.step == 0;
        for (std::size_t rest = k; rest < schedule.steps.size(); ++rest) {
          const auto& end = schedule.steps[rest];
          if (end.step == 1 && !end.frame && begun[end.fault]) {
            executed.push_back({lb::test::bus_now_ns(), end.fault, end.step, carry_out(line, schedule, end)});
          }
        }
        break;
      }
      if (!bus_process_down && !line.bridge_running()) {
        // Not the campaign's doing: a failure to report; started again, as the service manager would.
        ++ended_by_itself;
        say(fmt::format("[{}] the bridge's bus process ended by itself: started again\n",
                        Watcher::at(line, lb::test::bus_now_ns())));
        line.start_bus_process();
      }
      const bool done = carry_out(line, schedule, step);
      if (schedule.faults[step.fault].kind == campaign::FaultKind::kill_bus_process) bus_process_down = step.step == 0;
      const auto now = lb::test::bus_now_ns();
      executed.push_back({now, step.fault, step.step, done});
      if (step.step == 0) {
        say(fmt::format("[{}] fault {}: {}{}\n", Watcher::at(line, now), step.fault,
                        campaign::fault_text(schedule, step.fault), done ? "" : " (not done: no such process)"));
      }
    }
    (void)interrupt.wait_until(start + std::chrono::milliseconds(duration_ms));
    if (interrupt.signal() != 0) {
      say(fmt::format("[{}] signal {}: the campaign ends early; the verdict is on what ran\n",
                      Watcher::at(line, lb::test::bus_now_ns()), interrupt.signal()));
    }
    for (auto& op : operators) op->stop();
    max_load = std::max(max_load, watcher.max_load());
    if (!line.bridge_running()) {
      ++ended_by_itself;
      say(fmt::format("[{}] the bridge's bus process ended by itself\n", Watcher::at(line, lb::test::bus_now_ns())));
    }
    // Everything sent up to now is recorded once every bus has gone on for a second more.
    const auto until = lb::test::bus_now_ns() + 1'000'000'000;
    for (const auto& bus : line.buses()) {
      lb::test::eventually(std::chrono::seconds(30), [&] {
        const auto frames = line.frames(bus);
        return !frames.empty() && frames.back().timestamp_ns >= until;
      });
    }
  }

  const auto record = judge.record();
  const auto violations = judge.judge(record);
  const auto figures = campaign::StopFigures::of(judge, record, violations);
  std::size_t overflows = 0, frames = 0;
  for (const auto& bus : line.buses()) {
    for (const auto& f : line.frames(bus)) {
      overflows += f.error ? 1 : 0;
      ++frames;
    }
  }

  std::string out = fmt::format("\n== fault campaign: seed {}, {} min{} ==\n", seed, minutes,
                                interrupt.signal() == 0 ? "" : " (ended early by a signal)");
  out += "faults injected, by kind:\n";
  std::map<campaign::FaultKind, std::pair<std::size_t, std::size_t>> kinds;  // done, not done
  std::map<std::string, std::size_t> variants;
  for (const auto& e : executed) {
    if (e.step != 0) continue;
    const auto& f = schedule.faults[e.fault];
    (e.done ? kinds[f.kind].first : kinds[f.kind].second)++;
  }
  std::size_t total = 0;
  for (const auto k : campaign::kAllFaults) {
    const auto [done, not_done] = kinds[k];
    total += done;
    out += fmt::format("  {:<48} {:>4}{}\n", campaign::name(k), done,
                       not_done == 0 ? "" : fmt::format(" ({} not done: no such process then)", not_done));
  }
  out += fmt::format("  {:<48} {:>4}\n", "total", total);
  out += fmt::format("  {:<48} {:>4}\n", "bus-off (the virtual bus cannot emulate it)", "-");
  out += "stops sent by the operators, and what became of them:\n";
  std::size_t stops = 0;
  for (const auto& [kind, k] : figures.by_kind) {
    stops += k.sent;
    out += fmt::format(
        "  {:<48} {:>5} sent: {} accepted and on the bus, {} taken across an outage, {} refused (device not heard), "
        "{} refused (device NMT-stopped), {} unanswered (bridge down), {} violations\n",
        kind, k.sent, k.on_bus, k.across_outage, k.refused_not_heard, k.refused_nmt_stopped, k.unanswered_in_outage,
        k.judged_violation);
  }
  out += fmt::format("  {:<48} {:>5}\n", "total", stops);
  out += "time from a stop's request to its frame(s) on the bus:\n";
  out += "  accepted stops:                              " + campaign::percentiles(figures.latency_ns) + "\n";
  out += "  of which changed the bus (not already off):  " + campaign::percentiles(figures.changed_latency_ns) + "\n";
  out += "  taken across an outage (from the request):   " + campaign::percentiles(figures.outage_latency_ns) + "\n";
  out += fmt::format("frames recorded: {}; recorder overflows: {}\n", frames, overflows);
  out +=
      fmt::format("machine: {} cores, 1-minute load average {:.1f} at the start, {:.1f} at most (sampled every {} s)\n",
                  std::thread::hardware_concurrency(), load_at_start, max_load, judge_every_s);
  if (ended_by_itself > 0) out += fmt::format("the bridge's bus process ended by itself {} time(s)\n", ended_by_itself);
  out += fmt::format("violations: {}\n", violations.size());
  out += campaign::violations_by_kind(line, violations);
  const auto spoofed = line.spoofed();
  for (const auto& v : violations) out += campaign::describe(v, record, line, judge, schedule, executed, spoofed);
  out += fmt::format("seed {}\n", seed);
  say(out);
  operators.clear();  // their DDS entities before the line's participant
  if (overflows > 0) {
    say("the recorder lost frames: the verdict may miss violations\n");
    return 2;
  }
  if (!violations.empty() || ended_by_itself > 0) return 1;
  return interrupt.signal() == 0 ? 0 : 2;  // no violation in what ran, but it did not run its time
}
