// PDO decoding of every built-in profile (gateways/*_codec, drive_image, canopen/process_image):
// a device of any profile at any node-ID, its PDOs received with any payload, re-mapped as an
// adopting boot may find them (use_pdo), packed, rendered as DDS samples, and set values of any
// value (NaN, infinities, huge) validated and applied, in any order: nothing may crash, and a
// packed PDO never exceeds its mapping.
#include <fuzzer/FuzzedDataProvider.h>

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "gateways/codecs/drive_binding.hpp"
#include "gateways/codecs/drive_codec.hpp"
#include "gateways/codecs/feeder_codec.hpp"
#include "gateways/codecs/saw_codec.hpp"
#include "profiles/device_types.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"

using namespace lb;
using profiles::DevicePdo;
using profiles::Profile;

namespace {

constexpr int kMaxOps = 64;

std::vector<std::uint8_t> payload(FuzzedDataProvider& in) {
  return in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 8));
}

double value(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0: return in.ConsumeFloatingPointInRange<double>(-200, 200);
    case 1: return in.ConsumeFloatingPoint<double>();  // includes infinities and extremes
    case 2: return std::numeric_limits<double>::quiet_NaN();
    default: return static_cast<double>(in.ConsumeIntegral<std::int64_t>());
  }
}

// The PDO as a boot may find it on a device: its own mapping of profile objects (or of anything),
// identifier and transmission type.
DevicePdo found(FuzzedDataProvider& in, const Profile& profile, const DevicePdo& configured) {
  DevicePdo p = configured;
  p.can_id = in.ConsumeBool() ? p.can_id : in.ConsumeIntegralInRange<std::uint32_t>(0, 0x7FF);
  p.transmission_type = in.ConsumeIntegral<std::uint8_t>();
  if (in.ConsumeBool()) return p;
  p.mapping.resize(in.ConsumeIntegralInRange<std::size_t>(0, 9));
  for (auto& e : p.mapping) {
    if (!profile.objects.empty() && in.ConsumeBool()) {
      const auto& o = profile.objects[in.ConsumeIntegralInRange<std::size_t>(0, profile.objects.size() - 1)];
      e = {o.index, o.sub,
           static_cast<std::uint8_t>(in.ConsumeBool() ? canopen::bit_size(o.type)
                                                      : in.ConsumeIntegral<std::uint8_t>())};
    } else {
      e = canopen::PdoEntry::from_u32(in.ConsumeIntegral<std::uint32_t>());
    }
  }
  return p;
}

// What every codec shares: receive, re-map, pack.
template <class Codec>
bool common_op(FuzzedDataProvider& in, int op, Codec& codec, const Profile& profile) {
  const auto& pdos = codec.pdos();
  const std::size_t i = in.ConsumeIntegralInRange<std::size_t>(0, pdos.size() - 1);
  switch (op) {
    case 0: {
      const auto bytes = payload(in);
      (void)codec.receive(i, bytes);
      return true;
    }
    case 1: (void)codec.use_pdo(i, found(in, profile, *pdos[i].def)); return true;
    case 2: {
      std::array<std::uint8_t, 8> out{};
      if (codec.pack(i, out) > pdos[i].binding.mapping().byte_length()) __builtin_trap();
      return true;
    }
    default: return false;
  }
}

// Up to kMaxOps operations on codec: the shared ones (common_op, ops 0..2) and the type's own,
// type_op(op) for op 3..last_op.
template <class Codec, class TypeOp>
void run_ops(FuzzedDataProvider& in, Codec& codec, const Profile& profile, int last_op, TypeOp type_op) {
  for (int n = 0; n < kMaxOps && in.remaining_bytes() > 0; ++n) {
    const int op = in.ConsumeIntegralInRange<int>(0, last_op);
    if (!common_op(in, op, codec, profile)) type_op(op);
  }
}

void saw(FuzzedDataProvider& in, const Profile& profile, const std::vector<DevicePdo>& pdos) {
  gateways::SawCodec codec(profile, pdos);
  run_ops(in, codec, profile, 5, [&](int op) {
    if (op == 3) {
      linebridge_msgs::msg::SawStatus s;
      codec.fill(s);
      (void)codec.cutting();
    } else if (op == 4) {
      linebridge_msgs::msg::SawSetpoint sp;
      sp.saw_program_on(in.ConsumeBool());
      sp.count_mode(static_cast<linebridge_msgs::msg::SawCountMode>(in.ConsumeIntegralInRange<int>(0, 3)));
      sp.sync_speed_percent(value(in));
      sp.product_length_m(value(in));
      if (auto raw = codec.validate(sp)) codec.apply(*raw);
    } else {
      codec.set_control_bit(in.ConsumeIntegralInRange<unsigned>(0, 15), in.ConsumeBool());
    }
  });
}

template <class Codec>
void drive(FuzzedDataProvider& in, const Profile& profile, const std::vector<DevicePdo>& pdos) {
  Codec codec(profile, pdos);
  run_ops(in, codec, profile, 5, [&](int op) {
    if (op == 3) {
      typename Codec::Status s;
      codec.fill(s);
    } else if (op == 4) {
      typename Codec::Setpoint sp;
      sp.extruder_running(in.ConsumeBool());
      sp.speed_set_percent(value(in));
      if (auto raw = codec.validate(sp)) codec.apply(*raw);
    } else {
      codec.set_control_bit(in.ConsumeIntegralInRange<unsigned>(0, 15), in.ConsumeBool());
    }
  });
}

void feeder(FuzzedDataProvider& in, const Profile& profile, const std::vector<DevicePdo>& pdos) {
  gateways::FeederCodec codec(profile, pdos);
  run_ops(in, codec, profile, 6, [&](int op) {
    if (op == 3) {
      linebridge_msgs::msg::LoomSide loom;
      codec.fill_loom(loom, in.ConsumeBool());
      (void)codec.last_unwinding();
    } else if (op == 4) {
      const auto raw = in.ConsumeIntegral<std::uint32_t>();
      (void)codec.feeder_status(raw);
      (void)codec.error_condition(raw);
      (void)codec.control_box_error(raw);
      (void)codec.functions(raw);
      (void)codec.pick(static_cast<std::uint8_t>(raw));
      (void)codec.unwinding(raw);
      std::array<std::uint8_t, 5> manufacturer{};
      for (auto& b : manufacturer) b = in.ConsumeIntegral<std::uint8_t>();
      (void)gateways::FeederCodec::in_bitmap(gateways::FeederCodec::ff10_bitmap(manufacturer),
                                             in.ConsumeIntegralInRange<unsigned>(0, 40));
    } else if (op == 5) {
      linebridge_msgs::msg::LoomSetpoint sp;
      sp.loom_status(in.ConsumeRandomLengthString(24));
      sp.maximum_speed_per_min(in.ConsumeIntegral<std::uint16_t>());
      sp.loom_width_m(value(in));
      sp.trigger_signal(in.ConsumeRandomLengthString(24));
      sp.pick_insertion(in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 6)));
      if (auto raw = codec.validate(sp)) codec.apply(*raw);
    } else {
      const unsigned which = in.ConsumeIntegralInRange<unsigned>(0, 300);
      const std::optional<unsigned> count = in.ConsumeBool()
                                                ? std::nullopt
                                                : std::optional<unsigned>(in.ConsumeIntegralInRange<unsigned>(0, 300));
      (void)codec.number_assignment(which, in.ConsumeIntegral<std::uint8_t>(), count);
      (void)codec.color_assignment(which, in.ConsumeIntegral<std::uint8_t>(), count);
      (void)codec.command(which, in.ConsumeRandomLengthString(24), in.ConsumeIntegral<std::uint8_t>(), count);
      (void)codec.test(which, in.ConsumeRandomLengthString(24), in.ConsumeIntegral<std::uint8_t>(), count);
      (void)codec.weft_insertion_type(in.ConsumeRandomLengthString(24));
      (void)codec.trigger_sources({in.ConsumeRandomLengthString(24)}, in.ConsumeIntegral<std::uint64_t>());
      std::vector<gateways::FeederCodec::FunctionSetting> settings(1);
      settings[0].function = in.ConsumeRandomLengthString(24);
      settings[0].state = in.ConsumeRandomLengthString(24);
      (void)codec.merge_functions(in.ConsumeIntegral<std::uint64_t>(), settings);
    }
  });
}

std::vector<const Profile*> all_profiles(const profiles::ProfileRegistry& registry) {
  std::vector<const Profile*> out;
  for (const auto& key : registry.keys()) {
    const auto at = key.find('@');
    out.push_back(registry.find(key.substr(0, at), key.substr(at + 1)));
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto registry = profiles::ProfileRegistry::builtin();
  static const auto profiles = all_profiles(registry);
  FuzzedDataProvider in(data, size);
  const Profile& profile = *profiles[in.ConsumeIntegralInRange<std::size_t>(0, profiles.size() - 1)];
  const auto pdos = profiles::default_pdos(profile, in.ConsumeIntegralInRange<std::uint8_t>(1, 127));
  // A profile of a device no codec serves traps: the registry (profiles/device_types.hpp) lacks it.
  const auto* type = profiles::find_device_type(profile.device);
  if (type == nullptr) __builtin_trap();
  switch (type->behaviour) {
    case profiles::Behaviour::saw: saw(in, profile, pdos); break;
    case profiles::Behaviour::feeder: feeder(in, profile, pdos); break;
    case profiles::Behaviour::drive:
      if (!gateways::visit_drive(type->idl,
                                 [&]<class Binding>() { drive<gateways::DriveCodec<Binding>>(in, profile, pdos); })) {
        __builtin_trap();
      }
      break;
  }
  return 0;
}
