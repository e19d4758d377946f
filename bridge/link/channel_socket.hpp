#pragma once
// The channel's socket: a Unix SOCK_SEQPACKET socket on a file path (message boundaries kept,
// connection-oriented, so a dead peer is noticed at once). The file is mode 0660 (its directory
// should be the service's, e.g. /run/linebridge): the kernel lets the service's user and group
// connect. Who of them is the DDS side is the bus side's to decide from each peer's credentials
// (SO_PEERCRED, taken by the kernel at connect, not claimed by the peer): exactly one user, and,
// when the bus process starts its DDS process itself, only that child (PeerRule).

#include <sys/types.h>
#include <unistd.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "can/unique_fd.hpp"
#include "link/channel_message.hpp"

namespace lb::link {

using can::UniqueFd;

// Room for one datagram of the channel (up to kMaxMessage bytes). Not zeroed: its pages become
// resident only as far as datagrams reach (most are under 1 KiB), not 256 KiB per reader at start.
class DatagramBuffer {
 public:
  std::span<std::uint8_t> room() { return {bytes_.get(), kMaxMessage}; }
  std::span<const std::uint8_t> first(std::size_t n) const { return {bytes_.get(), n}; }

 private:
  std::unique_ptr<std::uint8_t[]> bytes_ = std::make_unique_for_overwrite<std::uint8_t[]>(kMaxMessage);
};

// Binds and listens on `path` (an old socket file left by a killed process is replaced; anything
// else there is an error), non-blocking.
Result<UniqueFd> listen_channel(const std::string& path);

// A peer accepted from a listening socket (non-blocking), with its credentials as the kernel took
// them at connect.
struct Peer {
  UniqueFd fd;
  pid_t pid = 0;
  uid_t uid = 0;
  gid_t gid = 0;
};
Result<Peer> accept_channel(int listener);

// Who may be the DDS side. Not a group: a group's members are whoever an administrator adds to it
// (to read the line file, say), and a process of any user whose primary group is the service's
// would pass. Not root either: a root process does not need the channel to reach the bus.
struct PeerRule {
  uid_t uid = ::geteuid();      // the DDS side's user (systemd: linebridge-dds; else this process's)
  bool own_child_only = false;  // --part both: only a child of this process (the DDS process it started)
};
// Why the peer is not the DDS side; empty when it is.
std::string refusal(const Peer& peer, const PeerRule& rule);
// The parent of a process (/proc/PID/stat); 0 when it cannot be read (gone, hidden).
pid_t parent_of(pid_t pid);

// Connects to a listening channel (blocking socket, with send and receive timeouts).
Result<UniqueFd> connect_channel(const std::string& path, int timeout_ms);

// A lane (docs/bus-isolation.md): a connected pair of SOCK_SEQPACKET sockets, made by the bus
// process for each connection of a DDS side; `bus` non-blocking, `dds` handed to that DDS side.
struct LanePair {
  UniqueFd bus;
  UniqueFd dds;
};
Result<LanePair> make_lane();

// One datagram with descriptors attached (SCM_RIGHTS), never blocking: false when the socket did
// not take it whole.
bool send_with_fds(int socket, std::span<const std::uint8_t> datagram, std::span<const int> fds);
// One datagram and the descriptors attached to it (at most max_fds; the ones beyond are closed),
// waiting as the socket's receive timeout says. Descriptors arrive close-on-exec.
struct Received {
  std::size_t size = 0;
  std::vector<UniqueFd> fds;
};
Result<Received> receive_with_fds(int socket, std::span<std::uint8_t> buffer, std::size_t max_fds);

}  // namespace lb::link
