#include "canopen/boot_sequence.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>

namespace lb::canopen {

namespace {

struct IdentityObject {
  std::uint16_t index;
  std::uint8_t sub;
  DataType type;
  const char* name;
};

// 1000h is read first, as the presence check; 1018h sub 1 is mandatory, the rest optional.
constexpr std::array<IdentityObject, 7> kIdentity{{
    {0x1018, 1, DataType::unsigned32, "vendor-ID"},
    {0x1018, 2, DataType::unsigned32, "product code"},
    {0x1018, 3, DataType::unsigned32, "revision number"},
    {0x1018, 4, DataType::unsigned32, "serial number"},
    {0x1008, 0, DataType::visible_string, "device name"},
    {0x1009, 0, DataType::visible_string, "hardware version"},
    {0x100A, 0, DataType::visible_string, "software version"},
}};

std::uint32_t as_u32(const ObjectValue& v) {
  if (const auto* u = std::get_if<std::uint64_t>(&v)) return static_cast<std::uint32_t>(*u);
  return 0;
}

}  // namespace

BootSequence::BootSequence(BusLoop& loop, RemoteNode& node, SdoClient& sdo, std::vector<Write> writes,
                           std::chrono::milliseconds retry_interval, Listener listener)
    : loop_(loop), node_(node), sdo_(sdo), writes_(std::move(writes)), retry_interval_(retry_interval),
      listener_(std::move(listener)) {
  retry_timer_ = loop_.create_timer([this] { begin(); });
  node_.on_boot_up([this] { begin(); });
}

void BootSequence::begin() {
  const std::uint64_t gen = ++generation_;
  loop_.disarm_timer(retry_timer_);
  set_state("checking presence");
  sdo_.read(node_.node_id(), 0x1000, 0, DataType::unsigned32, [this, gen](SdoClient::ReadResult r) {
    if (gen != generation_) return;
    if (!r) return fail(gen, "not answering: " + r.error().message);
    write_next(gen, 0);
  });
}

void BootSequence::write_next(std::uint64_t gen, std::size_t i) {
  if (i == writes_.size()) return started(gen);
  set_state("configuring (" + std::to_string(i + 1) + "/" + std::to_string(writes_.size()) + ")");
  const auto& w = writes_[i];
  sdo_.write(node_.node_id(), w.index, w.sub, w.type, w.value, [this, gen, i](SdoClient::DownloadResult r) {
    if (gen != generation_) return;
    if (!r) {
      const auto& w2 = writes_[i];
      return fail(gen, fmt::format("configuration write {:04X}h:{:02X}h = {} refused: {}", w2.index, w2.sub,
                                   to_string(w2.value), r.error().message));
    }
    write_next(gen, i + 1);
  });
}

void BootSequence::started(std::uint64_t gen) {
  if (auto r = node_.command(NmtCommand::start); !r) return fail(gen, "NMT start failed: " + r.error().message);
  set_state("started");
  spdlog::info("{}: node {} configured ({} SDO writes) and started", loop_.bus().uri(), node_.node_id(), writes_.size());
  read_identity(gen, std::make_shared<DeviceIdentity>(), 0);
}

void BootSequence::read_identity(std::uint64_t gen, std::shared_ptr<DeviceIdentity> id, std::size_t step) {
  if (step == 0) {
    sdo_.read(node_.node_id(), 0x1000, 0, DataType::unsigned32, [this, gen, id](SdoClient::ReadResult r) {
      if (gen != generation_) return;
      if (r) id->device_type = as_u32(*r);
      else id->remarks += "1000h: " + r.error().message + "; ";
      read_identity(gen, id, 1);
    });
    return;
  }
  if (step > kIdentity.size()) {
    id->read_at_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                         std::chrono::system_clock::now().time_since_epoch()).count();
    if (listener_.on_identity) listener_.on_identity(*id);
    return;
  }
  const auto& obj = kIdentity[step - 1];
  sdo_.read(node_.node_id(), obj.index, obj.sub, obj.type, [this, gen, id, step, obj](SdoClient::ReadResult r) {
    if (gen != generation_) return;
    if (!r) {
      id->remarks += std::string(obj.name) + ": " + r.error().message + "; ";
    } else {
      switch (step) {
        case 1: id->vendor_id = as_u32(*r); break;
        case 2: id->product_code = as_u32(*r); break;
        case 3: id->revision_number = as_u32(*r); break;
        case 4: id->serial_number = as_u32(*r); break;
        case 5: id->device_name = std::get<std::string>(*r); break;
        case 6: id->hardware_version = std::get<std::string>(*r); break;
        default: id->software_version = std::get<std::string>(*r); break;
      }
    }
    read_identity(gen, id, step + 1);
  });
}

void BootSequence::fail(std::uint64_t gen, const std::string& why) {
  if (gen != generation_) return;
  set_state(why);
  spdlog::warn("{}: node {} {}; trying again in {} ms", loop_.bus().uri(), node_.node_id(), why, retry_interval_.count());
  loop_.arm_timer(retry_timer_, retry_interval_);
}

void BootSequence::set_state(std::string state) {
  state_ = std::move(state);
  if (listener_.on_state) listener_.on_state(state_);
}

}  // namespace lb::canopen
