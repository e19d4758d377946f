#pragma once
// The messages between a line's bus process and its DDS process (docs/bus-isolation.md): one
// SOCK_SEQPACKET datagram each, little-endian, a version in every header. Neither side trusts the
// other's bytes: decode() checks every length against the datagram and refuses what does not fit.
// The bus side declares the DDS endpoints it needs (topic, type, QoS kind) and exchanges samples
// as their CDR serialization (encapsulation header included), so the DDS side needs no type of
// the contract and the bus side no DDS.

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "base/result.hpp"

namespace lb::link {

// A change of any message's layout is a new version; the sides refuse each other's otherwise.
inline constexpr std::uint16_t kChannelVersion = 2;
// The largest datagram either side sends or accepts. The bus side refuses (counts, logs) a sample
// whose datagram would be larger, and gives each DDS side's socket a send buffer that holds one
// this large (BusChannel). SDO uploads, the largest bounded payloads of the contract, are at most
// 64 KiB; the line's diagnostics grow with its devices.
inline constexpr std::size_t kMaxMessage = 256 * 1024;

// A DDS sample identity (writer GUID, sequence number) without Fast DDS's type.
struct Identity {
  std::array<std::uint8_t, 16> guid{};
  std::int32_t seq_high = 0;
  std::uint32_t seq_low = 0;
  bool operator==(const Identity&) const = default;
};

// bus -> dds, first on every connection, with the DDS ends of the bus side's lanes attached
// (SCM_RIGHTS, lanes of them: lane k is the k-th descriptor).
struct Hello {
  std::uint16_t version = kChannelVersion;
  std::string line;
  std::uint64_t incarnation = 0;  // the bus process's run (every service answer names it)
  std::int32_t pid = 0;
  std::uint64_t connection = 0;  // this connection's number: the DDS side stamps its lane samples with it
  std::uint32_t lanes = 0;
};
// bus -> dds: an endpoint the DDS side creates; `id` names it in samples both ways.
struct Declare {
  std::uint32_t id = 0;
  bool writer = true;
  bool any_partition = false;  // a reader of writers in every partition
  std::uint8_t qos_kind = 0;   // ddsl::QosKind
  std::int32_t keep_last = 0;  // readers: a deeper keep-last history (0: the kind's)
  std::uint32_t max_size = 0;  // the type's largest serialized size
  std::string topic;
  std::string type;
  std::string partition;
  // Readers: the lane (1..Hello::lanes) their samples go to, straight to the bus loop that handles
  // them; 0 (or a lane the DDS side was not given): the channel itself.
  std::uint32_t lane = 0;
};
// bus -> dds: every endpoint declared and the snapshot sent; the DDS side may report ready.
struct Ready {
  std::uint32_t endpoints = 0;
};
// Both ways: one sample of a declared endpoint. bus -> dds: `related` set on a reply. dds -> bus:
// the sample's identity, its related identity, and for an any-partition reader the partitions
// its writer was matched in (checked at discovery).
struct Sample {
  std::uint32_t id = 0;
  std::uint64_t connection = 0;  // dds -> bus: Hello::connection (a lane drops other connections' samples)
  Identity identity;
  Identity related;
  std::vector<std::string> partitions;
  std::vector<std::uint8_t> payload;
};
// bus -> dds, every second: the bus side is alive (the DDS side's watchdog waits for it).
struct Ping {};
// dds -> bus, every second: what the bus side cannot see of DDS, for the line's diagnostics.
struct DdsStats {
  std::uint32_t remote_participants = 0;
  std::uint64_t remote_participants_refused = 0;
  std::uint64_t samples_not_forwarded = 0;  // to the bus side: it did not take them in time
};

using Message = std::variant<Hello, Declare, Ready, Sample, Ping, DdsStats>;

std::vector<std::uint8_t> encode(const Message& message);
// A datagram received: its message, or why it is not one (wrong version, truncated, trailing bytes).
Result<Message> decode(std::span<const std::uint8_t> datagram);

}  // namespace lb::link
