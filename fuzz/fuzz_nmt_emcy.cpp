// EMCY and NMT/heartbeat handling of one device as the master sees it (canopen/emcy,
// heartbeat_consumer, remote_node) fed arbitrary frames on its EMCY and heartbeat identifiers,
// other nodes' frames and the master's own NMT commands and boots in any order: nothing may crash,
// the active-error list stays bounded and free of duplicates, a monitor never transmits, and a
// master sends only NMT commands to this node.
#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/cob_id.hpp"
#include "canopen/emcy.hpp"
#include "canopen/nmt.hpp"
#include "canopen/remote_node.hpp"
#include "support/scripted_bus.hpp"

using namespace lb;

namespace {

constexpr std::uint8_t kNode = 5;
constexpr int kMaxSteps = 300;
constexpr canopen::NmtCommand kCommands[] = {canopen::NmtCommand::start, canopen::NmtCommand::stop,
                                             canopen::NmtCommand::enter_pre_operational,
                                             canopen::NmtCommand::reset_node, canopen::NmtCommand::reset_communication};

std::vector<canopen::PdoInUse> fuzzed_pdos(FuzzedDataProvider& in) {
  std::vector<canopen::PdoInUse> pdos(in.ConsumeIntegralInRange<std::size_t>(0, 3));
  for (auto& p : pdos) {
    p.name = "tpdo" + std::to_string(in.ConsumeIntegralInRange<int>(1, 4));
    p.parameters.cob_id = in.ConsumeIntegral<std::uint32_t>();
    p.parameters.transmission_type = in.ConsumeIntegral<std::uint8_t>();
    p.adopted = in.ConsumeBool();
  }
  return pdos;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  const bool master = in.ConsumeBool();
  canopen::RemoteNode* node = nullptr;
  std::vector<fuzz::ScriptedBus::Step> steps;
  while (in.remaining_bytes() > 0 && steps.size() < kMaxSteps) {
    switch (in.ConsumeIntegralInRange<int>(0, 11)) {
      case 0: {
        const auto command = kCommands[in.ConsumeIntegralInRange<std::size_t>(0, std::size(kCommands) - 1)];
        steps.push_back({std::nullopt, [&node, command] { (void)node->command(command); }});
        break;
      }
      case 1: {
        const bool configured = in.ConsumeBool();
        steps.push_back({std::nullopt, [&node, configured] { node->set_configured(configured); }});
        break;
      }
      case 2: {
        auto pdos = fuzzed_pdos(in);
        steps.push_back({std::nullopt, [&node, pdos] { (void)node->use_pdos(pdos); }});
        break;
      }
      case 3: {  // any other 11-bit frame: SYNC, NMT, other nodes, RTR
        auto f = fuzz::fuzzed_frame(in, in.ConsumeIntegralInRange<std::uint32_t>(0, 0x7FF));
        f.rtr = in.ConsumeBool();
        steps.push_back({f, {}});
        break;
      }
      case 4:
      case 5:
      case 6:
      case 7: steps.push_back({fuzz::fuzzed_frame(in, canopen::cob::emcy_base + kNode), {}}); break;
      default: steps.push_back({fuzz::fuzzed_frame(in, canopen::cob::heartbeat_base + kNode), {}}); break;
    }
  }

  auto owned = std::make_unique<fuzz::ScriptedBus>(std::move(steps));
  fuzz::ScriptedBus& bus = *owned;
  canopen::BusLoop loop(std::move(owned));
  canopen::RemoteNode remote(loop, kNode, std::chrono::minutes(1), master);  // no timeout within one input
  // What a gateway plugged into the node hears (canopen::NodeDriver).
  struct Driver final : canopen::NodeDriver {
    std::uint64_t emergencies = 0;
    void on_emcy(const canopen::Emergency& e) noexcept override {
      ++emergencies;
      (void)canopen::emcy_family(e.error_code);
    }
    void on_event(canopen::NodeEvent e) noexcept override { (void)canopen::to_string(e); }
    Result<void> on_config(std::span<const canopen::PdoInUse> pdos) noexcept override {
      if (pdos.size() > 2) return make_error("too many");
      return {};
    }
  } driver;
  remote.attach(driver);
  const std::uint64_t& emergencies = driver.emergencies;
  node = &remote;
  fuzz::run_script(loop, bus);

  const auto& codes = remote.errors().codes();
  if (codes.size() > canopen::ActiveErrors::kMax) __builtin_trap();
  for (std::size_t i = 0; i < codes.size(); ++i) {
    if (codes[i] == 0 || std::count(codes.begin(), codes.end(), codes[i]) != 1) __builtin_trap();
  }
  if (remote.stats().emergencies < emergencies) __builtin_trap();
  for (const auto& f : bus.sent()) {
    if (!master) __builtin_trap();
    if (f.id != canopen::cob::nmt || f.len != 2 || f.data[1] != kNode) __builtin_trap();
  }
  return 0;
}
