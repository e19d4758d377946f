#include "sim/feeder_simulator.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <stdexcept>

#include "canopen/sdo_abort.hpp"
#include "sim/device_dictionary.hpp"
#include "sim/little_endian.hpp"

namespace lb::sim {

namespace {

// A pre-measuring feeder reports one winding this often while the loom runs.
constexpr auto kWindingPeriod = std::chrono::milliseconds(100);
constexpr std::uint16_t kFeederError = 0xFF10;  // CiA 414-2: bitmap of the feeders in error

// EMCY FF10h's manufacturer bytes: the bitmap, little-endian.
std::array<std::uint8_t, 5> bitmap_bytes(std::uint32_t bitmap) {
  return {static_cast<std::uint8_t>(bitmap), static_cast<std::uint8_t>(bitmap >> 8),
          static_cast<std::uint8_t>(bitmap >> 16), static_cast<std::uint8_t>(bitmap >> 24), 0};
}

// Arrays with one element per feeder: sub 0 tells how many feeders the box has.
constexpr const char* kPerFeeder[] = {
    "feeder_functions", "single_weft_filling_parameter",   "feeder_error_condition", "feeder_status", "feeder_command",
    "feeder_test",      "system_feeder_number_assignment", "feeder_color_assignment"};

std::uint64_t code_of(const profiles::ObjectDef& obj, std::string_view name) {
  const auto c = obj.values.code(name);
  if (!c) throw std::runtime_error("profile object " + obj.name + " has no code '" + std::string(name) + "'");
  return *c;
}

}  // namespace

FeederSimulator::FeederSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device,
                                 const profiles::Profile& profile)
    : loop_(loop),
      device_(device),
      profile_(profile),
      node_(loop, device, profile,
            // CiA 414-2 4.6: "At each winding inserted the pre-measuring feeder transmits this TPDO."
            {[this] { reset(); },
             {},
             [this](std::span<const canopen::PdoEntry> mapped) { on_rpdo(mapped); },
             {"tpdo1"}}) {
  loom_status_ = node_.slot("loom_status");
  unwinding_time_ = node_.slot("feeder_unwinding_time");
  add_objects();
  unwind_timer_ = loop_.create_timer([this] { unwind(); });
  loop_.arm_timer(unwind_timer_, kWindingPeriod, kWindingPeriod);
}

const profiles::ObjectDef& FeederSimulator::object(std::string_view name) const {
  const auto* def = profile_.object(name);
  if (def == nullptr) throw std::runtime_error(device_.name + ": profile has no object " + std::string(name));
  return *def;
}

const profiles::BitSet& FeederSimulator::bitset(std::string_view name) const {
  const auto* set = profile_.bitset(name);
  if (set == nullptr) throw std::runtime_error(device_.name + ": profile has no bit set " + std::string(name));
  return *set;
}

void FeederSimulator::start() {
  spdlog::info("sim {}: feeder control box with {} feeders; fault injection: SDO write {:04X}h", device_.name, kFeeders,
               kFaultInjection);
  node_.boot();
}

void FeederSimulator::reset() {
  for (const auto* array : kPerFeeder) node_.set(object(std::string(array) + "_count").index, 0, kFeeders);
  const auto operational = code_of(object("feeder_status_1"), "operational_mode");
  // Plausible functions: brush release and yarn quality not available, S winding, the rest off or
  // not active except the yarn break sensor.
  const auto& fns = bitset("feeder_functions");
  std::uint64_t functions = 0;
  const std::pair<const char*, const char*> defaults[] = {{"brush_release", "not_available"},
                                                          {"winding_direction", "s"},
                                                          {"angle_trigger_monitoring", "off"},
                                                          {"yarn_break_sensor", "active"},
                                                          {"input_knot_detection_sensor", "not_active"},
                                                          {"yarn_quality_sensor", "not_available"},
                                                          {"rotation_direction_sensor", "not_active"},
                                                          {"tks_sensor", "not_available"}};
  for (const auto& [field, state] : defaults) {
    const auto* f = fns.field(field);
    if (f != nullptr && f->values.code(state)) functions = f->insert(functions, *f->values.code(state));
  }
  for (unsigned n = 1; n <= kFeeders; ++n) {
    const auto sub = static_cast<std::uint8_t>(n);
    node_.set(object("feeder_status_1").index, sub, operational);
    node_.set(object("feeder_error_condition_1").index, sub, 0);
    node_.set(object("feeder_functions_1").index, sub, functions);
    node_.set(object("system_feeder_number_assignment_1").index, sub, n);  // spec defaults: 01h, 02h, ...
    node_.set(object("feeder_color_assignment_1").index, sub, n);
  }
  const auto& sources = bitset("trigger_sources_supported");
  std::uint64_t supported = 0;
  for (const auto* name :
       {"brush_release_via_canopen", "angle_trigger_via_canopen", "pick_release_trigger_via_canopen"}) {
    if (auto b = sources.bit(name)) supported |= std::uint64_t{1} << *b;
  }
  const auto& supported_obj = object("trigger_sources_supported");
  node_.set(supported_obj.index, supported_obj.sub, supported);
  node_.set(object("trigger_sources_selected").index, object("trigger_sources_selected").sub, 0x01);  // spec default
  node_.set(object("trigger_signal_source_count").index, 0, 2);
  node_.set(object("pick_insertion_count").index, 0, 5);
  bitmap_ = 0;
  loom_running_ = false;
  node_.image().set(loom_status_, 0);
  node_.image().set(unwinding_time_, 0);
}

void FeederSimulator::add_objects() {
  node_.add_command(kFaultInjection, canopen::DataType::unsigned16,
                    [this](std::span<const std::uint8_t> v) { return on_fault_injection(little_endian(v)); });
  for (unsigned n = 1; n <= kFeeders; ++n) {
    const auto sub = static_cast<std::uint8_t>(n);
    node_.check_writes(object("feeder_command_1").index, sub,
                       [this, n](std::span<const std::uint8_t> v) { return on_command(n, little_endian(v)); });
    node_.check_writes(object("feeder_functions_1").index, sub,
                       [this, n](std::span<const std::uint8_t> v) { return on_functions(n, little_endian(v)); });
  }
  const auto& selected = object("trigger_sources_selected");
  const auto& supported = object("trigger_sources_supported");
  node_.check_writes(selected.index, selected.sub,
                     [this, &supported](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
                       if ((little_endian(v) & ~node_.get(supported.index, supported.sub)) != 0)
                         return canopen::sdo_abort::value_range_exceeded;
                       return std::nullopt;
                     });
}

std::optional<std::uint32_t> FeederSimulator::on_fault_injection(std::uint64_t value) {
  const unsigned feeder = value & 0xFF;
  const std::uint64_t condition = value >> 8;
  if (feeder > kFeeders) return canopen::sdo_abort::value_range_exceeded;
  if (feeder == 0) {
    for (unsigned n = 1; n <= kFeeders; ++n) clear(n);
  } else if (condition == 0) {
    clear(feeder);
  } else {
    raise(feeder, condition);
  }
  return std::nullopt;
}

std::optional<std::uint32_t> FeederSimulator::on_command(unsigned feeder, std::uint64_t command) {
  const auto& cmd = object("feeder_command_1");
  const auto& status = object("feeder_status_1");
  const auto sub = static_cast<std::uint8_t>(feeder);
  if (!cmd.values.name(command)) return canopen::sdo_abort::value_range_exceeded;  // 60h..FFh reserved
  if (command == code_of(cmd, "reset")) {
    clear(feeder);
    node_.set(status.index, sub, code_of(status, "operational_mode"));
  } else if ((bitmap_ >> (feeder - 1) & 1U) != 0) {
    return canopen::sdo_abort::cannot_store_device_state;  // a feeder in error takes only reset
  } else if (command == code_of(cmd, "operation_mode")) {
    node_.set(status.index, sub, code_of(status, "operational_mode"));
  } else if (command == code_of(cmd, "non_operation_mode") || command == code_of(cmd, "stop_mode")) {
    node_.set(status.index, sub, code_of(status, "non_operational_mode"));
  } else if (command == code_of(cmd, "start")) {
    node_.set(status.index, sub, code_of(status, "filling_up_to_maximum_sensor"));
  }
  spdlog::info("sim {}: feeder {} command {:02X}h ({})", device_.name, feeder, command, *cmd.values.name(command));
  return std::nullopt;
}

std::optional<std::uint32_t> FeederSimulator::on_functions(unsigned feeder, std::uint64_t word) {
  // "Only those functions and sensors that are marked as supported can be changed."
  const std::uint64_t current = node_.get(object("feeder_functions_1").index, static_cast<std::uint8_t>(feeder));
  for (const auto& f : bitset("feeder_functions").bits) {
    const auto now = f.extract(current), wanted = f.extract(word);
    if (!f.values.name(wanted)) return canopen::sdo_abort::value_range_exceeded;
    if (now != wanted && f.values.name(now) == "not_available") return canopen::sdo_abort::value_range_exceeded;
  }
  return std::nullopt;
}

void FeederSimulator::raise(unsigned feeder, std::uint64_t condition) {
  const auto sub = static_cast<std::uint8_t>(feeder);
  const auto& status = object("feeder_status_1");
  // The first error of a feeder is its main error: a second one does not replace it.
  if ((bitmap_ >> (feeder - 1) & 1U) == 0) node_.set(object("feeder_error_condition_1").index, sub, condition);
  node_.set(status.index, sub, code_of(status, "error_mode"));
  bitmap_ |= 1U << (feeder - 1);
  spdlog::info("sim {}: feeder {} fault {:02X}h injected: EMCY FF10h bitmap {:08X}h", device_.name, feeder, condition,
               bitmap_);
  node_.raise_error(kFeederError, bitmap_bytes(bitmap_));
}

void FeederSimulator::clear(unsigned feeder) {
  if ((bitmap_ >> (feeder - 1) & 1U) == 0) return;
  const auto sub = static_cast<std::uint8_t>(feeder);
  const auto& status = object("feeder_status_1");
  node_.set(object("feeder_error_condition_1").index, sub, 0);
  node_.set(status.index, sub, code_of(status, "operational_mode"));
  bitmap_ &= ~(1U << (feeder - 1));
  spdlog::info("sim {}: feeder {} fault cleared: EMCY FF10h bitmap {:08X}h", device_.name, feeder, bitmap_);
  // FF10h with the feeders still in error; once none is left, its last word and the error reset.
  if (bitmap_ != 0)
    node_.raise_error(kFeederError, bitmap_bytes(bitmap_));
  else
    node_.clear_error(kFeederError, bitmap_bytes(0));
}

void FeederSimulator::on_rpdo(std::span<const canopen::PdoEntry> mapped) {
  const auto& loom = object("loom_status");
  const bool carries_loom_status = std::any_of(mapped.begin(), mapped.end(), [&](const canopen::PdoEntry& e) {
    return e.index == loom.index && e.sub == loom.sub;
  });
  if (!carries_loom_status) return;
  const auto status = node_.image().get(loom_status_);
  if (status == code_of(loom, "new_speed_only")) return;  // "no change of loom status"
  const bool running = status == code_of(loom, "start_advice") || status == code_of(loom, "slow_motion_forward") ||
                       status == code_of(loom, "slow_motion_backward");
  if (running != loom_running_) spdlog::info("sim {}: loom {}", device_.name, running ? "running" : "stopped");
  loom_running_ = running;
}

void FeederSimulator::unwind() {
  if (!loom_running_ || node_.state() != canopen::NmtState::operational) return;
  const auto& status = object("feeder_status_1");
  const auto operational = code_of(status, "operational_mode");
  // The next feeder in operation inserts the weft (one feeder selected at a time).
  for (unsigned tries = 0; tries < kFeeders; ++tries) {
    next_feeder_ = next_feeder_ % kFeeders + 1;
    if (node_.get(status.index, static_cast<std::uint8_t>(next_feeder_)) == operational) break;
    if (tries + 1 == kFeeders) return;
  }
  winding_ = winding_ % 50 + 1;
  const auto& u = bitset("feeder_unwinding_time");
  std::uint64_t word = u.field("feeder_selected")->insert(0, next_feeder_);
  word = u.field("winding_number")->insert(word, winding_);
  word = u.field("coil_unwinding_time")->insert(word, 250 + 3 * winding_);  // 25.3..40 ms, raw 0.1 ms
  node_.image().set(unwinding_time_, word);
  node_.event("tpdo1");  // every winding is an event, even with the same word
}

}  // namespace lb::sim
