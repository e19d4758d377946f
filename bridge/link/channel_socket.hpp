#pragma once
// The channel's socket: a Unix SOCK_SEQPACKET socket on a file path (message boundaries kept,
// connection-oriented, so a dead peer is noticed at once). Only the service's own user and group
// reach it: the file is mode 0660 (its directory should be the service's, e.g. /run/linebridge),
// and each connecting peer's credentials (SO_PEERCRED) must name the listener's user, its group,
// or root.

#include <sys/types.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "can/unique_fd.hpp"

namespace lb::link {

using can::UniqueFd;

// Binds and listens on `path` (an old socket file left by a killed process is replaced; anything
// else there is an error), non-blocking.
Result<UniqueFd> listen_channel(const std::string& path);

// A peer accepted from a listening socket (non-blocking), or why it was not: its credentials are
// checked against this process's user and group.
struct Peer {
  UniqueFd fd;
  pid_t pid = 0;
  uid_t uid = 0;
  gid_t gid = 0;
};
Result<Peer> accept_channel(int listener);

// Connects to a listening channel (blocking socket, with send and receive timeouts).
Result<UniqueFd> connect_channel(const std::string& path, int timeout_ms);

}  // namespace lb::link
