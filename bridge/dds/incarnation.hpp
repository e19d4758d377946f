#pragma once
// Which run of the bridge a service request is meant for. A request ledger (request_ledger.hpp)
// lives as long as the bridge process: a client that sent a request to a bridge that was then
// killed (kill -9, a crash, systemd restarting it) and asks again after the new bridge is up would
// find it in no ledger and have it run a second time: a second manual cut, a second NMT reset.
// So every bridge process draws an incarnation at its start, publishes it (Diagnostics, every
// reply), and a client names the incarnation it last heard in each request; a bridge runs only
// requests that name its own or none (0: an old client, a tool that wants no check), and refuses
// the others unrun. The refusal cannot say whether the first bridge ran the request: the client
// must look at the device and decide. A request that stops a machine is the exception: it runs on
// any run (ServiceServer's Stops), since a stop is never refused while the device is heard.

#include <cstdint>
#include <string_view>

namespace lb::ddsl {

using Incarnation = std::uint64_t;

// A request that names no bridge: it runs on whichever takes it (the behaviour before incarnations).
inline constexpr Incarnation kAnyIncarnation = 0;

// 64 random bits from the system's entropy source, never kAnyIncarnation. Random, not the pid or a
// clock: a container restarts its bridge with the same pid, and a clock can be set back.
Incarnation draw_incarnation();

// Whether a request naming `named` may run on a bridge whose incarnation is `own`.
constexpr bool meant_for(Incarnation named, Incarnation own) { return named == kAnyIncarnation || named == own; }

// What a refused request is answered (the reply names the bridge that refused it, so a client can
// also tell this refusal by the incarnations: a reply naming another bridge than its request did).
inline constexpr std::string_view kRestartedRefusal =
    "refused: the bridge restarted since this request was first sent, so it did not run here; it may or may "
    "not have run before the restart: look at the device's state and ask again";

// A reply to a request that named `named`, from the bridge `answered_by`: this refusal, not an
// answer of its own (a stop runs on any run and may fail there for other reasons).
constexpr bool refused_as_restarted(Incarnation named, Incarnation answered_by, bool success,
                                    std::string_view message) {
  return named != kAnyIncarnation && answered_by != named && !success && message == kRestartedRefusal;
}

}  // namespace lb::ddsl
