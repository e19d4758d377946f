#include "canopen/identity_reader.hpp"

#include <fmt/format.h>

#include <chrono>
#include <memory>
#include <utility>
#include <vector>

#include "canopen/sdo_abort.hpp"
#include "canopen/sdo_batch.hpp"

namespace lb::canopen {

namespace {

std::string hex32(std::uint32_t v) { return fmt::format("{:04X} {:04X}h", v >> 16, v & 0xFFFF); }

std::int64_t wall_clock_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// One identity value against its expectation (CiA 302-2: D vendor-ID, M product code, N revision,
// O serial number); nullopt when it matches or is not checked.
std::optional<BootError> compare_identity(char code, const char* what, const char* key, std::uint8_t sub,
                                          std::optional<std::uint32_t> expected, std::uint32_t actual,
                                          std::uint8_t node) {
  if (!expected || *expected == actual) return std::nullopt;
  return BootError{code,
                   "identity",
                   0x1018,
                   sub,
                   hex32(*expected),
                   hex32(actual),
                   0,
                   fmt::format("node {}: {} (1018h sub {}) is {}, the line expects {} (identity.{}): this is not the "
                               "device the line configures at this node-ID",
                               node, what, sub, hex32(actual), hex32(*expected), key)};
}

// The replies to 1000h and 1018h sub 1..4 (as run_sdo_batch gives them: up to the first that
// failed) against what the line expects.
IdentityReader::Check judge(const std::vector<SdoReply>& r, const ExpectedIdentity& want, std::uint8_t node) {
  IdentityReader::Check c;
  const auto& failed = r.back().error;
  if (failed && r.size() == 1) {
    c.error = BootError{'B',
                        "device type",
                        0x1000,
                        0,
                        "an answer",
                        "none",
                        failed->abort_code,
                        fmt::format("node {} does not answer 1000h: {}", node, failed->message)};
    return c;
  }
  const auto type = static_cast<std::uint32_t>(unsigned_value(r[0]));
  auto& id = c.identity;
  id.device_type = type;
  if ((type & 0xFFFF) != want.profile_number) {
    c.answered = !failed;
    c.error =
        BootError{'C',
                  "device type",
                  0x1000,
                  0,
                  fmt::format("profile {}", want.profile_number),
                  fmt::format("{} (profile {})", hex32(type), type & 0xFFFF),
                  0,
                  fmt::format("node {}: device type {} is profile {}, the line configures a profile {} device here",
                              node, hex32(type), type & 0xFFFF, want.profile_number)};
  } else if (want.device_type && *want.device_type != type) {
    c.answered = !failed;
    c.error = BootError{'C',
                        "device type",
                        0x1000,
                        0,
                        hex32(*want.device_type),
                        hex32(type),
                        0,
                        fmt::format("node {}: device type (1000h) is {}, the line expects {} (identity.device_type)",
                                    node, hex32(type), hex32(*want.device_type))};
  }
  if (failed) {
    // 1018h refused: what was read of it stays 0, and a wrong device type found before still counts first.
    const std::uint8_t sub = static_cast<std::uint8_t>(r.size() - 1);
    if (!c.error) {
      c.error = BootError{"DMNO"[sub - 1],
                          "identity",
                          0x1018,
                          sub,
                          "an answer",
                          "abort",
                          failed->abort_code,
                          fmt::format("node {}: identity 1018h sub {} cannot be read: {}", node, sub, failed->message)};
    }
    return c;
  }
  c.answered = true;
  id.vendor_id = static_cast<std::uint32_t>(unsigned_value(r[1]));
  id.product_code = static_cast<std::uint32_t>(unsigned_value(r[2]));
  id.revision_number = static_cast<std::uint32_t>(unsigned_value(r[3]));
  id.serial_number = static_cast<std::uint32_t>(unsigned_value(r[4]));
  const std::pair<std::optional<std::uint32_t>, const char*> absent[] = {{want.product_code, "product code"},
                                                                         {want.revision, "revision number"},
                                                                         {want.serial_number, "serial number"}};
  for (std::size_t i = 0; i < 3; ++i) {
    if (!r[i + 2].absent) continue;
    id.remarks += std::string(absent[i].second) + ": not implemented; ";
    if (absent[i].first && !c.error) {
      const char code = "MNO"[i];
      const auto sub = static_cast<std::uint8_t>(i + 2);
      c.error = BootError{code,
                          "identity",
                          0x1018,
                          sub,
                          hex32(*absent[i].first),
                          "absent",
                          sdo_abort::no_such_sub_index,
                          fmt::format("node {}: the line expects {} {} but the device has no 1018h sub {}", node,
                                      absent[i].second, hex32(*absent[i].first), sub)};
    }
  }
  for (auto e :
       {compare_identity('D', "vendor-ID", "vendor_id", 1, want.vendor_id, id.vendor_id, node),
        compare_identity('M', "product code", "product_code", 2, want.product_code, id.product_code, node),
        compare_identity('N', "revision number", "revision", 3, want.revision, id.revision_number, node),
        compare_identity('O', "serial number", "serial_number", 4, want.serial_number, id.serial_number, node)}) {
    if (e && !c.error) c.error = std::move(e);
  }
  return c;
}

struct Name {
  std::uint16_t index;
  const char* what;
  std::string DeviceIdentity::*field;
};
constexpr Name kNames[] = {{0x1008, "device name", &DeviceIdentity::device_name},
                           {0x1009, "hardware version", &DeviceIdentity::hardware_version},
                           {0x100A, "software version", &DeviceIdentity::software_version}};

// The names one after the other: each optional object's abort is a remark and the next is asked;
// after a timeout (the device does not answer) the rest is not.
struct NameReading {
  SdoClient& sdo;
  std::uint8_t node;
  IdentityReader::Cancelled cancelled;
  std::function<void(DeviceIdentity)> done;
  DeviceIdentity identity;
  bool timed_out = false;
};

void next_name(const std::shared_ptr<NameReading>& n, std::size_t i) {
  if (i == std::size(kNames)) {
    n->identity.read_at_ns = wall_clock_ns();
    return n->done(std::move(n->identity));
  }
  const Name& name = kNames[i];
  if (n->timed_out) {
    n->identity.remarks += fmt::format("{}: not read (no answer before); ", name.what);
    return next_name(n, i + 1);
  }
  run_sdo_batch(n->sdo, n->node, {SdoRequest::read(name.index, 0, DataType::visible_string, true)}, n->cancelled,
                [n, i](const std::vector<SdoReply>& r) {
                  const Name& asked = kNames[i];
                  const auto& reply = r.back();
                  if (reply.value) {
                    if (const auto* s = std::get_if<std::string>(&*reply.value)) n->identity.*asked.field = *s;
                  } else if (reply.absent) {
                    n->identity.remarks += fmt::format("{}: not implemented; ", asked.what);
                  } else {
                    n->identity.remarks += fmt::format("{}: {}; ", asked.what, reply.error->message);
                    n->timed_out = reply.error->abort_code == sdo_abort::timed_out;
                  }
                  next_name(n, i + 1);
                });
}

}  // namespace

IdentityReader::IdentityReader(SdoClient& sdo, std::uint8_t node, const ExpectedIdentity& expected)
    : sdo_(sdo), node_(node), expected_(expected) {}

void IdentityReader::check(Cancelled cancelled, std::function<void(Check)> done) const {
  run_sdo_batch(sdo_, node_,
                {SdoRequest::read(0x1000, 0, DataType::unsigned32), SdoRequest::read(0x1018, 1, DataType::unsigned32),
                 SdoRequest::read(0x1018, 2, DataType::unsigned32, true),
                 SdoRequest::read(0x1018, 3, DataType::unsigned32, true),
                 SdoRequest::read(0x1018, 4, DataType::unsigned32, true)},
                std::move(cancelled),
                [this, done = std::move(done)](const std::vector<SdoReply>& r) { done(judge(r, expected_, node_)); });
}

void IdentityReader::read_names(DeviceIdentity identity, Cancelled cancelled,
                                std::function<void(DeviceIdentity)> done) const {
  next_name(std::make_shared<NameReading>(
                NameReading{sdo_, node_, std::move(cancelled), std::move(done), std::move(identity), false}),
            0);
}

void IdentityReader::read_all(const Cancelled& cancelled, std::function<void(Reading)> done) const {
  check(cancelled, [this, cancelled, done = std::move(done)](Check c) mutable {
    if (!c.answered) {
      c.identity.read_at_ns = wall_clock_ns();
      return done(Reading{std::move(c), std::nullopt});
    }
    auto identity = std::move(c.identity);
    read_names(std::move(identity), cancelled,
               [this, cancelled, c = std::move(c), done = std::move(done)](DeviceIdentity named) mutable {
                 c.identity = std::move(named);
                 run_sdo_batch(sdo_, node_, {SdoRequest::read(0x1017, 0, DataType::unsigned16, true)}, cancelled,
                               [c = std::move(c), done = std::move(done)](const std::vector<SdoReply>& r) mutable {
                                 Reading reading{std::move(c), std::nullopt};
                                 const auto& hb = r.back();
                                 if (hb.value) {
                                   reading.heartbeat_producer_ms = static_cast<std::uint16_t>(unsigned_value(hb));
                                 } else {
                                   reading.check.identity.remarks +=
                                       hb.absent
                                           ? std::string("heartbeat producer time 1017h: not implemented; ")
                                           : fmt::format("heartbeat producer time 1017h: {}; ", hb.error->message);
                                 }
                                 done(std::move(reading));
                               });
               });
  });
}

}  // namespace lb::canopen
