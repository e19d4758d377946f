// The SDO server's state machine (canopen/sdo_server, the simulators' side) fed arbitrary request
// sequences: nothing may crash, every answer is one 8-byte frame on 580h + node-ID, and the
// dictionary never holds a value its type, size or limits refuse.
#include <fuzzer/FuzzedDataProvider.h>

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/cob_id.hpp"
#include "canopen/object_value.hpp"
#include "canopen/sdo_server.hpp"
#include "support/scripted_bus.hpp"

using namespace lb;
using canopen::DataType;
using canopen::ObjectAccess;

namespace {

constexpr std::uint8_t kNode = 5;
constexpr int kMaxSteps = 300;

// A small dictionary with every kind of entry the server treats differently.
canopen::ObjectDictionary dictionary() {
  canopen::ObjectDictionary d;
  (void)d.add(0x1000, 0, DataType::unsigned32, ObjectAccess::ro, {0x94, 0x01, 0x04, 0x00});
  (void)d.add(0x1008, 0, DataType::visible_string, ObjectAccess::const_, {'s', 'a', 'w'});
  (void)d.add(0x1017, 0, DataType::unsigned16, ObjectAccess::rw);
  (void)d.add(0x2000, 0, DataType::unsigned8, ObjectAccess::wo);
  (void)d.add(0x2001, 1, DataType::integer16, ObjectAccess::rw, {}, -100, 100);
  (void)d.add(0x2001, 2, DataType::unsigned64, ObjectAccess::rw);
  (void)d.add(0x2002, 0, DataType::visible_string, ObjectAccess::rw);
  (void)d.add(0x2003, 0, DataType::octet_string, ObjectAccess::rw, std::vector<std::uint8_t>(20, 0xAA));
  (void)d.add(0x2004, 0, DataType::real32, ObjectAccess::rw);
  (void)d.add(0x2005, 0, DataType::boolean, ObjectAccess::rw);
  (void)d.add(0x2006, 0, DataType::unsigned32, ObjectAccess::rw);
  (void)d.ignore_writes(0x2006, 0);
  (void)d.add(0x2007, 0, DataType::unsigned16, ObjectAccess::rw);
  // Refuses odd values, as a device refuses a write in its present state.
  (void)d.set_on_write(0x2007, 0, [](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    if (v.size() != 2) __builtin_trap();  // the server checks the size before any hook
    if ((v[0] & 1) != 0) return 0x0800'0022U;
    return std::nullopt;
  });
  (void)d.add(0x2008, 0, DataType::octet_string, ObjectAccess::ro);
  (void)d.set_on_read(0x2008, 0, [] { return std::vector<std::uint8_t>(30, 0x55); });
  return d;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  canopen::SdoServer* server = nullptr;
  bool gate_open = true;
  std::vector<fuzz::ScriptedBus::Step> steps;
  while (in.remaining_bytes() > 0 && steps.size() < kMaxSteps) {
    switch (in.ConsumeIntegralInRange<int>(0, 15)) {
      case 0: steps.push_back({std::nullopt, [&server] { server->reset(); }}); break;
      case 1: steps.push_back({std::nullopt, [&gate_open] { gate_open = !gate_open; }}); break;
      case 2: {  // another node's request, or a frame of another kind on our identifier
        auto f = fuzz::fuzzed_frame(in, canopen::cob::sdo_rx_base + in.ConsumeIntegralInRange<std::uint32_t>(1, 127));
        f.rtr = in.ConsumeBool();
        steps.push_back({f, {}});
        break;
      }
      default: steps.push_back({fuzz::fuzzed_frame(in, canopen::cob::sdo_rx_base + kNode), {}}); break;
    }
  }

  auto owned = std::make_unique<fuzz::ScriptedBus>(std::move(steps));
  fuzz::ScriptedBus& bus = *owned;
  canopen::BusLoop loop(std::move(owned));
  canopen::SdoServer sdo(loop, kNode, dictionary());
  sdo.set_gate([&gate_open] { return gate_open; });
  server = &sdo;
  fuzz::run_script(loop, bus);

  for (const auto& f : bus.sent()) {
    if (f.id != canopen::cob::sdo_tx_base + kNode || f.len != 8 || f.extended || f.rtr) __builtin_trap();
  }
  const auto& d = sdo.dictionary();
  constexpr std::pair<std::uint16_t, std::uint8_t> kFixedSize[] = {{0x1017, 0}, {0x2001, 1}, {0x2001, 2},
                                                                   {0x2004, 0}, {0x2005, 0}, {0x2007, 0}};
  for (const auto& [index, sub] : kFixedSize) {
    const auto* e = d.find(index, sub);
    if (e == nullptr || e->value.size() != canopen::sdo_size(e->type)) __builtin_trap();
  }
  const auto* limited = d.find(0x2001, 1);
  const auto v = static_cast<std::int16_t>(limited->value[0] | limited->value[1] << 8);
  if (v < -100 || v > 100) __builtin_trap();
  const auto* refused = d.find(0x2007, 0);
  if ((refused->value[0] & 1) != 0) __builtin_trap();
  const auto* ignored = d.find(0x2006, 0);
  for (auto b : ignored->value) {
    if (b != 0) __builtin_trap();
  }
  return 0;
}
