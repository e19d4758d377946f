#pragma once
// Another master on a bus the bridge masters: a SYNC (080h) or an NMT command (000h) it did not
// send, a frame on an RPDO identifier the bridge sends, or a heartbeat on the bridge's own
// node-ID. CiA 301/302 allow one SYNC producer and one NMT master per network; with two, a device
// takes alternating set values at every SYNC. The bridge never receives its own frames (SocketCAN
// raw sockets and virtual buses do not echo them), so every such frame is someone else's.
//
// Policy `yield`: only on evidence a spoofer cannot give with a few frames: a foreign SYNC
// producer that runs, i.e. a run of at least kEvidence SYNCs over at least kEvidenceSpan, none
// more than max_gap() after the previous one (max(kEvidenceGap, 3 x the bus's own SYNC period)),
// judged on the frames' timestamps (the bus's time). While it runs the bridge transmits nothing
// but stops on that bus (BusLoop::hold_transmission: no SYNC, RPDO, NMT, SDO or heartbeat;
// BusLoop::send_stop still sends a stop), so the devices follow one master. Only SYNCs of that
// run keep the yield: it ends kQuiet after the last one. A run that stops (a gap over max_gap())
// is over: the next SYNC begins a new run, which must give the whole evidence again, so a SYNC now
// and then neither starts a yield nor keeps one. Stray or spoofed frames (an NMT command, a
// heartbeat on the bridge's node-ID, a frame on an RPDO identifier, a few SYNCs) are reported but
// never silence the master: a service tool or one misconfigured TPDO must not take the line's
// SYNC away. (The heartbeat of a configured peer master is the other evidence CiA 302 gives; it
// is not configurable yet.) Policy `warn`: report and go on. Either way every such frame is
// counted, logged (at a bounded rate) and shown in the diagnostics.

#include <chrono>
#include <cstdint>
#include <string>

#include "base/log_rate.hpp"
#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class OtherMasterWatch {
 public:
  enum class Policy { yield, warn };
  static constexpr unsigned kEvidence = 20;  // SYNCs in one run: twice what a few spoofed frames give
  static constexpr std::chrono::milliseconds kEvidenceGap{250};
  static constexpr std::chrono::milliseconds kEvidenceSpan{2000};
  static constexpr std::chrono::seconds kQuiet{5};

  // Before the loop starts. own_node_id: the bridge's heartbeat node-ID (0: none).
  OtherMasterWatch(BusLoop& loop, Policy policy, std::uint8_t own_node_id);
  // Before the loop starts: an RPDO identifier the bridge sends.
  void watch_rpdo(std::uint32_t can_id, bool extended);
  // Before the loop starts: the period of the bus's own SYNC (zero: it produces none), so that a
  // slower other producer still makes a run.
  void own_sync_period(std::chrono::microseconds period) { own_period_ = period; }
  // Loop thread (or before the loop starts): a standby (docs/redundancy.md) expects the master's
  // frames while it stands by, and watches only once it masters the bus.
  void stand_by(bool on) { standing_by_ = on; }
  // The longest gap within a run of foreign SYNCs.
  std::chrono::nanoseconds max_gap() const;

  // Loop thread.
  bool yielding() const { return yielding_; }
  std::uint64_t frames() const { return frames_; }
  std::uint64_t yields() const { return yields_; }  // times the bridge began to yield
  const std::string& last() const { return last_; }

 private:
  void seen(const can::CanFrame& frame, const char* what);
  void sync_seen(const can::CanFrame& frame);
  void quiet();

  BusLoop& loop_;
  Policy policy_;
  BusLoop::TimerId quiet_timer_;
  std::chrono::microseconds own_period_{0};
  // The current run of foreign SYNCs (bus time, ns: each within max_gap() of the previous one).
  std::int64_t run_start_ns_ = 0;
  std::int64_t last_sync_ns_ = 0;
  std::uint64_t run_syncs_ = 0;
  std::uint64_t frames_ = 0;
  std::uint64_t yields_ = 0;
  bool yielding_ = false;
  bool standing_by_ = false;
  std::string last_;
  LogRate log_{2};
};

}  // namespace lb::canopen
