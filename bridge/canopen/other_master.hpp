#pragma once
// Another master on a bus the bridge masters: a SYNC (080h) or an NMT command (000h) it did not
// send, a frame on an RPDO identifier the bridge sends, or a heartbeat on the bridge's own
// node-ID. CiA 301/302 allow one SYNC producer and one NMT master per network; with two, a device
// takes alternating set values at every SYNC. The bridge never receives its own frames (SocketCAN
// raw sockets and virtual buses do not echo them), so every such frame is someone else's.
//
// Policy `yield`: only on evidence of a real master, its SYNC producer running: at least
// kEvidence SYNCs in a run, none more than kEvidenceGap after the previous one, over at least
// kEvidenceSpan (a burst is no producer). While it is heard the bridge
// transmits nothing at all on that bus (BusLoop::hold_transmission: no SYNC, RPDO, NMT, SDO or
// heartbeat), so the devices follow one master; it resumes once no SYNC came for kQuiet. Stray
// or spoofed frames (an NMT command, a heartbeat on the bridge's node-ID, a frame on an RPDO
// identifier, a few SYNCs, a SYNC now and then) are reported but never silence the master: a
// service tool or one misconfigured TPDO must not take the line's SYNC away. Policy `warn`:
// report and go on. Either way every such frame is counted, logged (at a bounded rate) and shown
// in the diagnostics.

#include <chrono>
#include <cstdint>
#include <string>

#include "base/log_rate.hpp"
#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class OtherMasterWatch {
 public:
  enum class Policy { yield, warn };
  static constexpr unsigned kEvidence = 10;
  static constexpr std::chrono::milliseconds kEvidenceGap{250};
  static constexpr std::chrono::milliseconds kEvidenceSpan{200};
  static constexpr std::chrono::seconds kQuiet{5};

  // Before the loop starts. own_node_id: the bridge's heartbeat node-ID (0: none).
  OtherMasterWatch(BusLoop& loop, Policy policy, std::uint8_t own_node_id);
  // Before the loop starts: an RPDO identifier the bridge sends.
  void watch_rpdo(std::uint32_t can_id, bool extended);

  // Loop thread.
  bool yielding() const { return yielding_; }
  std::uint64_t frames() const { return frames_; }
  const std::string& last() const { return last_; }

 private:
  void seen(const can::CanFrame& frame, const char* what);
  void sync_seen(const can::CanFrame& frame);
  void quiet();

  BusLoop& loop_;
  Policy policy_;
  BusLoop::TimerId quiet_timer_;
  // The current run of foreign SYNCs (each within kEvidenceGap of the previous one).
  std::chrono::steady_clock::time_point run_start_{}, last_sync_{};
  std::uint64_t run_syncs_ = 0;
  std::uint64_t frames_ = 0;
  bool yielding_ = false;
  std::string last_;
  LogRate log_{2};
};

}  // namespace lb::canopen
