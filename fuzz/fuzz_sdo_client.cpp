// The SDO client's state machine (canopen/sdo_client) fed arbitrary server answers interleaved
// with requests of every kind: nothing may crash, every request completes exactly once, and every
// frame the client sends is a well-formed SDO request to a node it was asked about.
#include <fuzzer/FuzzedDataProvider.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/cob_id.hpp"
#include "canopen/sdo_client.hpp"
#include "support/scripted_bus.hpp"

using namespace lb;

namespace {

constexpr int kMaxSteps = 200;

// Exactly-once: a second completion of one request is a bug the fuzzer must see as a crash.
struct Completions {
  std::vector<std::atomic<int>> counts;
  explicit Completions(std::size_t n) : counts(n) {}
  void done(std::size_t request) {
    if (counts[request].fetch_add(1) != 0) __builtin_trap();
  }
};

canopen::DataType fuzzed_type(FuzzedDataProvider& in) {
  return static_cast<canopen::DataType>(
      in.ConsumeIntegralInRange<int>(0, static_cast<int>(canopen::DataType::octet_string)));
}

canopen::ObjectValue fuzzed_value(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 4)) {
    case 0: return in.ConsumeIntegral<std::int64_t>();
    case 1: return in.ConsumeIntegral<std::uint64_t>();
    case 2: return in.ConsumeFloatingPoint<double>();
    case 3: return in.ConsumeRandomLengthString(64);
    default: return in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 64));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  canopen::SdoClient* client = nullptr;  // set before the loop runs the script
  std::vector<fuzz::ScriptedBus::Step> steps;
  std::size_t requests = 0;
  // Every request's callback, counted by its number; sized once the script is known.
  auto completions = std::make_shared<std::unique_ptr<Completions>>();

  while (in.remaining_bytes() > 0 && steps.size() < kMaxSteps) {
    const int kind = in.ConsumeIntegralInRange<int>(0, 7);
    if (kind >= 4) {  // an answer of server 1..3 (some of them to no request at all)
      const auto node = in.ConsumeIntegralInRange<std::uint32_t>(1, 3);
      steps.push_back({fuzz::fuzzed_frame(in, canopen::cob::sdo_tx_base + node), {}});
      continue;
    }
    // Node 0 and 128 are refused before anything is sent.
    const auto node = in.ConsumeIntegralInRange<std::uint8_t>(0, 4) == 4
                          ? std::uint8_t{128}
                          : in.ConsumeIntegralInRange<std::uint8_t>(0, 3);
    const auto index = in.ConsumeIntegral<std::uint16_t>();
    const auto sub = in.ConsumeIntegral<std::uint8_t>();
    const std::size_t id = requests++;
    auto done = [completions, id](auto) { (*completions)->done(id); };
    std::function<void()> action;
    switch (kind) {
      case 0: action = [&client, node, index, sub, done] { client->upload(node, index, sub, done); }; break;
      case 1: {
        auto bytes = in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 40));
        action = [&client, node, index, sub, bytes, done] { client->download(node, index, sub, bytes, done); };
        break;
      }
      case 2: {
        const auto type = fuzzed_type(in);
        action = [&client, node, index, sub, type, done] { client->read(node, index, sub, type, done); };
        break;
      }
      default: {
        const auto type = fuzzed_type(in);
        const auto value = fuzzed_value(in);
        action = [&client, node, index, sub, type, value, done] { client->write(node, index, sub, type, value, done); };
        break;
      }
    }
    steps.push_back({std::nullopt, std::move(action)});
  }
  *completions = std::make_unique<Completions>(requests);

  auto owned = std::make_unique<fuzz::ScriptedBus>(std::move(steps));
  fuzz::ScriptedBus& bus = *owned;
  {
    canopen::BusLoop loop(std::move(owned));
    {
      canopen::SdoClient sdo(loop, std::chrono::seconds(60));  // no timeout within one input
      client = &sdo;
      fuzz::run_script(loop, bus);
    }  // pending requests complete here, on this thread
    for (const auto& f : bus.sent()) {
      const bool to_server = f.id > canopen::cob::sdo_rx_base && f.id <= canopen::cob::sdo_rx_base + 3;
      if (!to_server || f.len != 8 || f.extended || f.rtr) __builtin_trap();
    }
  }
  for (const auto& c : (*completions)->counts) {
    if (c.load() != 1) __builtin_trap();
  }
  return 0;
}
