#pragma once
// The standby's watch on the active master (docs/redundancy.md): the master's heartbeat, on the
// line's master node-ID (which both bridges of a pair produce when they master the bus) or on the
// node-ID the active master gave in the negotiation (FlyingMaster). Silent for takeover_after
// (judged on bus time, once the frames queued meanwhile were read), the standby takes over: once, by
// calling on_takeover on the loop thread. A negotiation won (no master active) takes over too.
//
// It also keeps, from the bus alone, what a takeover continues: when the last SYNC was (so the
// first SYNC of the new master comes one period after it, not before) and the last NMT command
// the master sent each node (a device it held stopped or pre-operational stays so).

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "canopen/bus_loop.hpp"
#include "canopen/nmt.hpp"

namespace lb::canopen {

class ActiveMasterWatch {
 public:
  struct Takeover {
    bool master_heard = false;           // a master's heartbeat was heard while this bridge stood by
    std::uint8_t master_node_id = 0;     // the master watched (the line's, or the one a negotiation named)
    std::int64_t last_heartbeat_ns = 0;  // the master's last heartbeat (bus time), 0: none
    std::int64_t last_sync_ns = 0;       // the last SYNC on the bus (bus time), 0: none
    std::int64_t at_ns = 0;              // when the silence was judged (realtime)
  };

  // Before the loop starts.
  ActiveMasterWatch(BusLoop& loop, std::uint8_t master_node_id, std::chrono::milliseconds takeover_after,
                    std::function<void(const Takeover&)> on_takeover);
  ActiveMasterWatch(const ActiveMasterWatch&) = delete;
  ActiveMasterWatch& operator=(const ActiveMasterWatch&) = delete;

  // Loop thread: watch this master's heartbeat from now on (its silence counted from now if none of
  // it was heard yet).
  void stand_by(std::uint8_t master_node_id);
  // Loop thread: master the bus now (a negotiation won): on_takeover, with what was heard so far.
  void claim();

  // Loop thread from here on. It took the bus over (once per run).
  bool active() const { return takeover_.has_value(); }
  // The last NMT command the master sent to this node (to it alone, or to all), if any since this
  // bridge stood by.
  std::optional<NmtCommand> last_command(std::uint8_t node_id) const;
  // When this bridge's first SYNC after the takeover went out (realtime), told by whoever sends it.
  void first_sync_sent(std::int64_t at_ns) { first_sync_ns_ = at_ns; }
  // The takeover in words, with its SYNC gap as measured (diagnostics); empty: none.
  std::string describe() const;

 private:
  void heartbeat(const can::CanFrame& frame);
  void judge();
  void take_over(std::int64_t now);

  BusLoop& loop_;
  std::uint8_t master_node_id_;         // the one watched now
  std::array<bool, 128> registered_{};  // heartbeat handlers registered, per node-ID
  std::chrono::milliseconds takeover_after_;
  std::function<void(const Takeover&)> on_takeover_;
  BusLoop::TimerId timer_;
  bool watching_ = false;
  std::optional<Takeover> takeover_;
  std::int64_t first_sync_ns_ = 0;
  std::int64_t started_ns_ = 0;
  std::int64_t last_heartbeat_ns_ = 0;
  std::int64_t last_sync_ns_ = 0;
  // Per node-ID (index 0 unused): the last NMT command byte seen for it, 0: none.
  std::array<std::uint8_t, 128> commands_{};
};

}  // namespace lb::canopen
