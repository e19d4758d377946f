#pragma once
// When a device's status sample goes out (status_publish, docs/dds-contract.md). No PDO's data is
// ever overwritten before it was published: a PDO that arrives again while its previous copy still
// waits publishes first.
//
// per_frame: one sample per burst of PDOs (BusLoop::request_flush): the PDOs of one device that
// arrive together (after a SYNC, or while the loop was busy) go out as one sample, stamped with the
// newest frame's time.
// per_cycle (a CycleDeadline given): a synchronous TPDO that arrives while a SYNC's cycle is open
// waits for the rest of the device's cycle: the sample goes as soon as every TPDO the device sends
// at each SYNC (transmission type 1) is in, or at the cycle's deadline. Other PDOs, and synchronous
// ones with no cycle open (no SYNC heard), go per burst as above.

#include <algorithm>
#include <cstdint>
#include <functional>

#include "canopen/bus_loop.hpp"
#include "canopen/cycle_deadline.hpp"

namespace lb::gateways {

class PdoBurst {
 public:
  // What the device's PDO configuration says of a PDO just decoded (pdo_receive.hpp: cycle_of).
  struct Timing {
    bool synchronous = false;     // a TPDO sent after SYNCs (transmission type 0..240)
    std::uint64_t each_sync = 0;  // the device's TPDOs sent at every SYNC (type 1), as PDO index bits
  };

  // publish: the gateway's status publication; it must call published(). cycle: null for per_frame.
  PdoBurst(canopen::BusLoop& loop, canopen::CycleDeadline* cycle, std::function<void(std::int64_t stamp_ns)> publish)
      : loop_(loop), cycle_(cycle), publish_(std::move(publish)), flush_(loop.create_flush([this] { flush(); })) {
    if (cycle_ != nullptr) waiter_ = cycle_->create_waiter([this] { flush(); });
  }
  PdoBurst(const PdoBurst&) = delete;
  PdoBurst& operator=(const PdoBurst&) = delete;

  // Loop thread, before decoding PDO `index`: publishes what waits if this PDO is part of it.
  void admit(std::size_t index) {
    if ((waiting_ & bit(index)) != 0) publish_(stamp_ns_);
  }
  // Loop thread, after decoding it: the sample goes out at the end of the burst, or of the cycle.
  // timing_of() -> Timing is asked only while a cycle is open: per_frame, and per_cycle with no
  // SYNC heard, cost no look at the PDO configuration per frame.
  template <class TimingOf>
  void add(std::size_t index, std::int64_t stamp_ns, const TimingOf& timing_of) {
    waiting_ |= bit(index);
    stamp_ns_ = stamp_ns;
    if (cycle_ != nullptr && cycle_->open()) {
      if (const Timing timing = timing_of(); timing.synchronous) {
        if (timing.each_sync != 0 && (waiting_ & timing.each_sync) == timing.each_sync) return publish_(stamp_ns_);
        return cycle_->wait(waiter_);
      }
    }
    loop_.request_flush(flush_);
  }
  // The gateway published its status (for whatever reason): nothing waits any more.
  void published() { waiting_ = 0; }

  // Devices have a handful of PDOs; past 63 they share a bit, which only publishes earlier.
  static std::uint64_t bit(std::size_t index) { return std::uint64_t{1} << std::min<std::size_t>(index, 63); }

 private:
  void flush() {
    if (waiting_ != 0) publish_(stamp_ns_);
  }

  canopen::BusLoop& loop_;
  canopen::CycleDeadline* cycle_;
  std::function<void(std::int64_t)> publish_;
  canopen::BusLoop::FlushId flush_;
  canopen::CycleDeadline::WaiterId waiter_ = 0;
  std::uint64_t waiting_ = 0;  // a bit per PDO index decoded since the last sample
  std::int64_t stamp_ns_ = 0;
};

}  // namespace lb::gateways
