#pragma once
// A software CAN bus: any number of members, in one process or in several processes on one machine,
// with no kernel CAN support and no privileges. Used by the simulator, the demo and the tests.
//
// Semantics (those of a SocketCAN raw socket with default options):
//   - every frame a member sends reaches every other member, never the sender itself;
//   - all members see frames in one total order, as CAN arbitration gives;
//   - a member that does not read fast enough loses frames instead of slowing the bus down, and
//     learns it from an error frame (id CAN_ERR_CRTL, data[1] CAN_ERR_CRTL_RX_OVERFLOW), as a
//     controller reports an RX overrun;
//   - error frames a member sends are delivered as such (fault injection for tests, simulators).
//
// How: a hub reads the members' messages one at a time on one thread and forwards each to all
// members but its sender; that single sequence is the total order. The hub listens on the abstract
// unix address "\0linebridge-vbus/<name>" (SOCK_SEQPACKET, so one message is one frame). The first
// member to bind that address runs the hub on a thread of its own; every member, the owner
// included, is a client of the hub. When the hub goes away (its owner is destroyed or its process
// exits) fd() becomes readable, and the members elect a new one transparently in receive() (or in
// send(), whichever comes first). Frames in flight during that hand-over may be lost; frames a
// member tries to send in the gap fail and count in tx_dropped. Abstract addresses are per network
// namespace: all members must share one.
//
// fd() is an epoll descriptor owned by the bus that holds the current hub connection (and a retry
// timer while no hub is reachable). It never changes for the lifetime of the object, across any
// number of hand-overs: register it once, level-triggered, and call receive() when it is readable.
//
// Like every Bus, one object is used by one thread at a time. Do not fork() a process that owns a
// hub unless the child execs or _exits promptly: the child's copy of the listening socket would
// keep the address while no thread serves it.

#include <chrono>
#include <memory>
#include <string_view>

#include "can/bus.hpp"
#include "can/unique_fd.hpp"

namespace lb::can {

class VirtualBus final : public Bus {
  struct PrivateTag {
    explicit PrivateTag() = default;
  };

 public:
  // name: 1..91 characters of [A-Za-z0-9._-]. Returns once the hub has accepted this member, so
  // every frame any member sends after open() returns reaches it (a frame sent just before may too:
  // send() queues, like a controller's TX queue). Blocks at most 2 s, then fails if no hub answers.
  static Result<std::unique_ptr<VirtualBus>> open(std::string_view name);
  // The name rule above, checked before anything is opened (the line configuration checks it too).
  static Result<void> check_name(std::string_view name);

  VirtualBus(PrivateTag, std::string uri, std::string address, UniqueFd epoll, UniqueFd retry_timer);
  ~VirtualBus() override;

  const std::string& uri() const override { return uri_; }
  int fd() const override { return epoll_.get(); }
  Result<std::optional<CanFrame>> receive() override;
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override {
    BusStats s = stats_;
    s.state = BusState::error_active;  // a software bus has no error counters to leave that state
    return s;
  }

  // Whether this object currently runs the hub (for diagnostics and tests).
  bool owns_hub() const;

 private:
  class Hub;

  Result<bool> join();
  Result<void> rejoin();
  Result<bool> await_welcome(std::chrono::steady_clock::time_point deadline);
  void leave();
  void set_retry_timer(bool armed);

  std::string uri_;
  std::string address_;  // abstract unix address, leading NUL included
  UniqueFd epoll_;
  UniqueFd retry_timer_;
  struct RxBatch;

  std::unique_ptr<Hub> hub_;
  UniqueFd sock_;                // connection to the hub; empty while none is reachable
  std::unique_ptr<RxBatch> rx_;  // messages read by one recvmmsg, handed out one per receive()
  BusStats stats_;
};

}  // namespace lb::can
