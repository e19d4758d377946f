// The PDO parameter planner (canopen/pdo_parameters) with arbitrary wanted parameters, profile
// rules and device contents: a plan is refused with a reason, or its writes, applied to a model of
// the device in their order, obey CiA 301 (mapping entries only while sub 0 is 0, mapping and
// identifier changes only while the PDO is not valid, when the profile lets the master make it so)
// and leave the device holding exactly the plan's result, which verify_pdo then accepts.
#include <fuzzer/FuzzedDataProvider.h>

#include <cstdint>
#include <vector>

#include "canopen/pdo_parameters.hpp"

using namespace lb::canopen;

namespace {

PdoAccess fuzzed_access(FuzzedDataProvider& in) {
  return static_cast<PdoAccess>(in.ConsumeIntegralInRange<int>(0, static_cast<int>(PdoAccess::none)));
}

std::vector<PdoEntry> fuzzed_entries(FuzzedDataProvider& in, std::size_t max) {
  std::vector<PdoEntry> out(in.ConsumeIntegralInRange<std::size_t>(0, max));
  // Few distinct values, so that the device and the line often agree on some entries.
  for (auto& e : out) e = PdoEntry::from_u32(0x6000'0008U + in.ConsumeIntegralInRange<std::uint32_t>(0, 3) * 0x10000);
  return out;
}

PdoParameters fuzzed_parameters(FuzzedDataProvider& in, std::size_t max_entries) {
  PdoParameters p;
  p.cob_id = in.ConsumeBool()
                 ? in.ConsumeIntegral<std::uint32_t>()
                 : (in.ConsumeBool() ? kCobIdNotValid : 0U) | (in.ConsumeBool() ? kCobIdNoRtr : 0U) | 0x185U;
  p.transmission_type = in.ConsumeBool() ? 1 : in.ConsumeIntegral<std::uint8_t>();
  p.inhibit_time = in.ConsumeBool() ? 0 : in.ConsumeIntegral<std::uint16_t>();
  p.event_timer = in.ConsumeBool() ? 0 : in.ConsumeIntegral<std::uint16_t>();
  p.mapping = fuzzed_entries(in, max_entries);
  return p;
}

// The device as the writes change it: the mapping object's entries 1..n and its sub 0.
struct Model {
  PdoParameters p;
  std::vector<PdoEntry> entries;  // sub 1..
  bool can_invalidate;

  void write(const PdoSpec& spec, const PdoWrite& w, bool mapping_change) {
    if (w.index == spec.communication_index) {
      switch (w.sub) {
        case 1: {
          // The identifier changes only while the PDO is not valid (CiA 301 7.5.2.35).
          const bool identifier_change = ((w.value ^ p.cob_id) & ~kCobIdNotValid) != 0;
          if (identifier_change && p.valid() && (w.value & kCobIdNotValid) == 0 && can_invalidate) __builtin_trap();
          p.cob_id = w.value;
          break;
        }
        case 2: p.transmission_type = static_cast<std::uint8_t>(w.value); break;
        case 3: p.inhibit_time = static_cast<std::uint16_t>(w.value); break;
        case 5: p.event_timer = static_cast<std::uint16_t>(w.value); break;
        default: __builtin_trap();
      }
      return;
    }
    if (w.index != spec.mapping_index) __builtin_trap();
    if (mapping_change && p.valid() && can_invalidate) __builtin_trap();
    if (w.sub == 0) {
      if (w.value > entries.size() && w.value > 64) __builtin_trap();
      if (w.value > entries.size()) entries.resize(w.value);  // a device with room for them
      p.mapping.assign(entries.begin(), entries.begin() + w.value);
      return;
    }
    if (!p.mapping.empty()) __builtin_trap();  // entries are written while sub 0 is 0
    if (w.sub > entries.size()) entries.resize(w.sub);
    entries[w.sub - 1u] = PdoEntry::from_u32(w.value);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  PdoSpec spec;
  spec.name = "tpdo1";
  spec.transmit = in.ConsumeBool();
  spec.communication_index = spec.transmit ? 0x1800 : 0x1400;
  spec.mapping_index = spec.transmit ? 0x1A00 : 0x1600;
  spec.validity_given = in.ConsumeBool();
  spec.optional = in.ConsumeBool();
  spec.rules.cob_id = fuzzed_access(in);
  spec.rules.transmission_type = fuzzed_access(in);
  spec.rules.inhibit_time = fuzzed_access(in);
  spec.rules.event_timer = fuzzed_access(in);
  spec.rules.mapping_count = fuzzed_access(in);
  spec.rules.mapping = fuzzed_access(in);
  spec.rules.mapping_counts = in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 3));
  spec.rules.manufacturer_entries = in.ConsumeIntegralInRange<unsigned>(0, 2);
  spec.wanted = fuzzed_parameters(in, 8);

  DevicePdo device;
  device.absent = in.ConsumeIntegralInRange<int>(0, 15) == 0;
  device.has_inhibit_time = in.ConsumeIntegralInRange<int>(0, 3) != 0;
  device.has_event_timer = in.ConsumeIntegralInRange<int>(0, 3) != 0;
  device.parameters = fuzzed_parameters(in, 8);
  device.unmapped = fuzzed_entries(in, 4);
  const bool adopt = in.ConsumeBool();
  const PdoSpec used = adopt ? adopt_device_pdo(spec, device) : spec;

  const auto plan = plan_pdo(used, device);
  if (!plan) {
    if (plan.error().message.empty()) __builtin_trap();
    return 0;
  }
  if (device.absent) {
    if (!plan->writes.empty() || plan->result.valid()) __builtin_trap();
    return 0;
  }
  Model model{device.parameters, device.parameters.mapping,
              writable(used.rules.cob_id) || used.rules.cob_id == PdoAccess::valid_bit};
  model.entries.insert(model.entries.end(), device.unmapped.begin(), device.unmapped.end());
  for (const auto& w : plan->writes) model.write(used, w, plan->needs_not_operational);
  if (!(model.p == plan->result)) __builtin_trap();
  DevicePdo read_back = device;
  read_back.parameters = model.p;
  if (verify_pdo(used, plan->result, read_back)) __builtin_trap();
  (void)describe_cob_id(plan->result.cob_id);
  return 0;
}
