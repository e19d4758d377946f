#include "canopen/sdo_server.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <stdexcept>

#include "canopen/object_value.hpp"
#include "canopen/sdo_abort.hpp"

namespace lb::canopen {
namespace {

std::uint64_t raw_of(std::span<const std::uint8_t> bytes) {
  std::uint64_t raw = 0;
  for (std::size_t i = 0; i < bytes.size() && i < 8; ++i) raw |= std::uint64_t{bytes[i]} << (8 * i);
  return raw;
}

// The limits check of an SDO write whose size is already right.
std::optional<std::uint32_t> out_of_range(const ObjectDictionary::Entry& e, std::span<const std::uint8_t> value) {
  const std::uint64_t raw = raw_of(value);
  if (e.type == DataType::boolean && raw > 1) return sdo_abort::value_range_exceeded;
  if (e.type == DataType::real32 || e.type == DataType::real64) {
    const double d = e.type == DataType::real32 ? double{std::bit_cast<float>(static_cast<std::uint32_t>(raw))}
                                                : std::bit_cast<double>(raw);
    if (!e.min && !e.max) return std::nullopt;
    if (std::isnan(d)) return sdo_abort::value_range_exceeded;
    if (e.max && d > static_cast<double>(*e.max)) return sdo_abort::value_too_high;
    if (e.min && d < static_cast<double>(*e.min)) return sdo_abort::value_too_low;
    return std::nullopt;
  }
  if (is_signed_integer(e.type)) {
    const std::int64_t v = sign_extend(raw, bit_size(e.type));
    if (e.max && v > *e.max) return sdo_abort::value_too_high;
    if (e.min && v < *e.min) return sdo_abort::value_too_low;
    return std::nullopt;
  }
  if (is_unsigned_integer(e.type)) {
    // Limits are signed; an unsigned value compares as the number it is, not as its bit pattern.
    if (e.max && (*e.max < 0 || raw > static_cast<std::uint64_t>(*e.max))) return sdo_abort::value_too_high;
    if (e.min && *e.min > 0 && raw < static_cast<std::uint64_t>(*e.min)) return sdo_abort::value_too_low;
  }
  return std::nullopt;
}

}  // namespace

// ---- ObjectDictionary --------------------------------------------------------------------------

Result<void> ObjectDictionary::add(std::uint16_t index, std::uint8_t sub, DataType type, ObjectAccess access,
                                   Bytes value, std::optional<std::int64_t> min, std::optional<std::int64_t> max) {
  const std::size_t size = sdo_size(type);
  if (size != 0 && value.empty()) value.assign(size, 0);
  if (size != 0 && value.size() != size) {
    return make_error(fmt::format("{:04X}h:{:02X}: {} takes {} bytes, the initial value has {}", index, sub,
                                  to_string(type), size, value.size()));
  }
  entries_[key(index, sub)] = Entry{type, access, std::move(value), min, max, {}, {}, false};
  return {};
}

Result<void> ObjectDictionary::set_on_write(std::uint16_t index, std::uint8_t sub, WriteHook hook) {
  auto it = entries_.find(key(index, sub));
  if (it == entries_.end()) return make_error(fmt::format("{:04X}h:{:02X}: no such object", index, sub));
  it->second.on_write = std::move(hook);
  return {};
}

Result<void> ObjectDictionary::set_on_read(std::uint16_t index, std::uint8_t sub, ReadHook hook) {
  auto it = entries_.find(key(index, sub));
  if (it == entries_.end()) return make_error(fmt::format("{:04X}h:{:02X}: no such object", index, sub));
  it->second.on_read = std::move(hook);
  return {};
}

Result<void> ObjectDictionary::ignore_writes(std::uint16_t index, std::uint8_t sub) {
  auto it = entries_.find(key(index, sub));
  if (it == entries_.end()) return make_error(fmt::format("{:04X}h:{:02X}: no such object", index, sub));
  it->second.ignore_writes = true;
  return {};
}

const ObjectDictionary::Entry* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) const {
  auto it = entries_.find(key(index, sub));
  return it == entries_.end() ? nullptr : &it->second;
}

Result<void> ObjectDictionary::set(std::uint16_t index, std::uint8_t sub, Bytes value) {
  auto it = entries_.find(key(index, sub));
  if (it == entries_.end()) return make_error(fmt::format("{:04X}h:{:02X}: no such object", index, sub));
  const std::size_t size = sdo_size(it->second.type);
  if (size != 0 && value.size() != size) {
    return make_error(fmt::format("{:04X}h:{:02X}: {} takes {} bytes, got {}", index, sub, to_string(it->second.type),
                                  size, value.size()));
  }
  it->second.value = std::move(value);
  return {};
}

Result<const ObjectDictionary::Entry*, std::uint32_t> ObjectDictionary::lookup(std::uint16_t index,
                                                                               std::uint8_t sub) const {
  if (const Entry* e = find(index, sub)) return e;
  // CiA 301 tells "no such object" from "no such sub-index of an object that exists".
  auto it = entries_.lower_bound(key(index, 0));
  const bool index_exists = it != entries_.end() && (it->first >> 8) == index;
  return index_exists ? sdo_abort::no_such_sub_index : sdo_abort::no_such_object;
}

Result<ObjectDictionary::Bytes, std::uint32_t> ObjectDictionary::read(std::uint16_t index, std::uint8_t sub) const {
  auto e = lookup(index, sub);
  if (!e) return e.error();
  if ((*e)->access == ObjectAccess::wo) return sdo_abort::read_of_write_only;
  if ((*e)->on_read) return (*e)->on_read();
  return (*e)->value;
}

Result<void, std::uint32_t> ObjectDictionary::check_write(std::uint16_t index, std::uint8_t sub,
                                                          std::optional<std::size_t> size) const {
  auto e = lookup(index, sub);
  if (!e) return e.error();
  if ((*e)->access == ObjectAccess::ro || (*e)->access == ObjectAccess::const_) return sdo_abort::write_to_read_only;
  const std::size_t fixed = sdo_size((*e)->type);
  if (size && fixed != 0 && *size != fixed) return sdo_abort::length_mismatch;
  return {};
}

Result<void, std::uint32_t> ObjectDictionary::write(std::uint16_t index, std::uint8_t sub,
                                                    std::span<const std::uint8_t> value) {
  if (auto ok = check_write(index, sub, value.size()); !ok) return ok.error();
  Entry& e = entries_.at(key(index, sub));
  if (e.ignore_writes) return {};
  if (auto code = out_of_range(e, value)) return *code;
  if (e.on_write) {
    if (auto code = e.on_write(value)) return *code;
  }
  e.value.assign(value.begin(), value.end());
  return {};
}

// ---- SdoServer ---------------------------------------------------------------------------------

struct SdoServer::Core {
  enum class Mode { idle, downloading, uploading };
  using Payload = std::array<std::uint8_t, 8>;

  BusLoop& loop;
  std::uint8_t node;
  ObjectDictionary od;
  // Set by the destructor, which may run on another thread once the loop stopped.
  std::atomic<bool> closed{false};
  std::function<bool()> answering;  // loop thread

  // The one transfer a server has at a time (CiA 301): loop thread only.
  Mode mode = Mode::idle;
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  bool toggle = false;
  std::optional<std::size_t> size;  // download: as the client indicated it
  ObjectDictionary::Bytes buffer;   // download: received so far; upload: the value being sent
  std::size_t offset = 0;           // upload: bytes sent so far

  Core(BusLoop& l, std::uint8_t n, ObjectDictionary d) : loop(l), node(n), od(std::move(d)) {}

  void respond(const Payload& p) {
    can::CanFrame f;
    f.id = cob::sdo_tx_base + node;
    f.len = 8;
    std::copy(p.begin(), p.end(), f.data.begin());
    (void)loop.send(f);  // a lost response is the client's timeout; BusLoop counts and logs it
  }

  Payload initiate_response(std::uint8_t cmd) const {
    return {cmd, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
  }

  void abort(std::uint32_t code) {
    spdlog::debug("{}: SDO server {}: abort {:04X}h:{:02X} with {:08X}h ({})", loop.bus().uri(), node, index, sub, code,
                  sdo_abort_meaning(code));
    Payload p = initiate_response(0x80);
    for (int i = 0; i < 4; ++i) p[4 + i] = static_cast<std::uint8_t>(code >> (8 * i));
    respond(p);
    mode = Mode::idle;
  }

  // A segment outside a transfer of its direction; a segment names no object, so the abort names
  // the transfer it breaks, or none (0000h:00).
  void unexpected_segment() {
    if (mode == Mode::idle) {
      index = 0;
      sub = 0;
    }
    abort(sdo_abort::invalid_command_specifier);
  }

  void on_request(const can::CanFrame& f) {
    if (closed.load()) return;
    if (answering && !answering()) {
      mode = Mode::idle;  // silent: whatever was in progress is lost, as the client will see
      return;
    }
    const std::uint8_t cmd = f.data[0];
    const unsigned ccs = cmd >> 5;
    // Initiate, abort and unknown requests carry the multiplexor; segments refer to the transfer.
    if (ccs != 0 && ccs != 3) {
      index = static_cast<std::uint16_t>(f.data[1] | f.data[2] << 8);
      sub = f.data[3];
    }
    if (ccs == 4) {
      mode = Mode::idle;  // the client aborted: an abort is never answered
      return;
    }
    if (f.len != 8) return abort(sdo_abort::general_error);  // CiA 301: SDO frames have 8 bytes
    switch (ccs) {
      case 1: return download_initiate(cmd, f.data);
      case 0: return download_segment(cmd, f.data);
      case 2: return upload_initiate();
      case 3: return upload_segment(cmd);
      default: return abort(sdo_abort::invalid_command_specifier);  // 5, 6: block transfer; 7: none
    }
  }

  void download_initiate(std::uint8_t cmd, const std::array<std::uint8_t, 8>& d) {
    const bool expedited = cmd & 0x02;
    const bool size_indicated = cmd & 0x01;
    if (expedited) {
      std::size_t n = 4;
      if (size_indicated) {
        n = 4 - ((cmd >> 2) & 0x03);
      } else if (const auto* e = od.find(index, sub)) {
        // Size not indicated: the object's own size when it fits, else all four bytes.
        if (const std::size_t fixed = sdo_size(e->type); fixed != 0 && fixed < 4) n = fixed;
      }
      if (auto ok = od.write(index, sub, std::span(d).subspan(4, n)); !ok) return abort(ok.error());
      mode = Mode::idle;
      return respond(initiate_response(0x60));
    }
    size.reset();
    if (size_indicated) size = raw_of(std::span(d).subspan(4, 4));
    if (auto ok = od.check_write(index, sub, size); !ok) return abort(ok.error());
    mode = Mode::downloading;
    toggle = false;
    buffer.clear();
    respond(initiate_response(0x60));
  }

  void download_segment(std::uint8_t cmd, const std::array<std::uint8_t, 8>& d) {
    if (mode != Mode::downloading) return unexpected_segment();
    const bool t = cmd & 0x10;
    if (t != toggle) return abort(sdo_abort::toggle_bit_not_alternated);
    const std::size_t n = (cmd >> 1) & 0x07;
    buffer.insert(buffer.end(), d.begin() + 1, d.end() - static_cast<std::ptrdiff_t>(n));
    if (size && buffer.size() > *size) return abort(sdo_abort::length_mismatch);
    const std::uint8_t response = static_cast<std::uint8_t>(0x20 | (t ? 0x10 : 0));
    if (!(cmd & 0x01)) {
      toggle = !toggle;
      return respond({response, 0, 0, 0, 0, 0, 0, 0});
    }
    if (size && buffer.size() != *size) return abort(sdo_abort::length_mismatch);
    if (auto ok = od.write(index, sub, buffer); !ok) return abort(ok.error());
    mode = Mode::idle;
    respond({response, 0, 0, 0, 0, 0, 0, 0});
  }

  void upload_initiate() {
    auto value = od.read(index, sub);
    if (!value) return abort(value.error());
    buffer = std::move(*value);
    const std::size_t n = buffer.size();
    if (n >= 1 && n <= 4) {
      Payload p = initiate_response(static_cast<std::uint8_t>(0x43 | (4 - n) << 2));
      std::copy(buffer.begin(), buffer.end(), p.begin() + 4);
      mode = Mode::idle;
      return respond(p);
    }
    // Segmented, also for an empty value: expedited cannot say "zero bytes".
    Payload p = initiate_response(0x41);
    for (int i = 0; i < 4; ++i) p[4 + i] = static_cast<std::uint8_t>(n >> (8 * i));
    mode = Mode::uploading;
    toggle = false;
    offset = 0;
    respond(p);
  }

  void upload_segment(std::uint8_t cmd) {
    if (mode != Mode::uploading) return unexpected_segment();
    const bool t = cmd & 0x10;
    if (t != toggle) return abort(sdo_abort::toggle_bit_not_alternated);
    const std::size_t chunk = std::min<std::size_t>(7, buffer.size() - offset);
    const bool last = offset + chunk == buffer.size();
    Payload p{};
    p[0] = static_cast<std::uint8_t>((t ? 0x10 : 0) | (7 - chunk) << 1 | (last ? 1 : 0));
    std::copy_n(buffer.begin() + static_cast<std::ptrdiff_t>(offset), chunk, p.begin() + 1);
    offset += chunk;
    toggle = !toggle;
    if (last) mode = Mode::idle;
    respond(p);
  }
};

SdoServer::SdoServer(BusLoop& loop, std::uint8_t node_id, ObjectDictionary dictionary) {
  if (node_id < 1 || node_id > 127) throw std::invalid_argument(fmt::format("SDO server node-ID {}", node_id));
  core_ = std::make_shared<Core>(loop, node_id, std::move(dictionary));
  loop.on_frame(cob::sdo_rx_base + node_id, [core = core_](const can::CanFrame& f) { core->on_request(f); });
}

SdoServer::~SdoServer() { core_->closed.store(true); }

std::uint8_t SdoServer::node_id() const { return core_->node; }
void SdoServer::set_gate(std::function<bool()> answering) { core_->answering = std::move(answering); }
void SdoServer::reset() { core_->mode = Core::Mode::idle; }
ObjectDictionary& SdoServer::dictionary() { return core_->od; }
const ObjectDictionary& SdoServer::dictionary() const { return core_->od; }

}  // namespace lb::canopen
