#pragma once
// A device's status sample per burst of PDOs instead of per PDO (BusLoop::request_flush): the PDOs
// of one device that arrive together (after a SYNC, or while the loop was busy) go out as one
// sample, stamped with the newest frame's time. No PDO's data is ever overwritten before it was
// published: a PDO that arrives again while its previous copy still waits publishes first.

#include <algorithm>
#include <cstdint>
#include <functional>

#include "canopen/bus_loop.hpp"

namespace lb::gateways {

class PdoBurst {
 public:
  // publish: the gateway's status publication; it must call published().
  PdoBurst(canopen::BusLoop& loop, std::function<void(std::int64_t stamp_ns)> publish)
      : loop_(loop), publish_(std::move(publish)), flush_(loop.create_flush([this] {
          if (waiting_ != 0) publish_(stamp_ns_);
        })) {}
  PdoBurst(const PdoBurst&) = delete;
  PdoBurst& operator=(const PdoBurst&) = delete;

  // Loop thread, before decoding PDO `index`: publishes what waits if this PDO is part of it.
  void admit(std::size_t index) {
    if ((waiting_ & bit(index)) != 0) publish_(stamp_ns_);
  }
  // Loop thread, after decoding it: the sample goes out at the end of the burst.
  void add(std::size_t index, std::int64_t stamp_ns) {
    waiting_ |= bit(index);
    stamp_ns_ = stamp_ns;
    loop_.request_flush(flush_);
  }
  // The gateway published its status (for whatever reason): nothing waits any more.
  void published() { waiting_ = 0; }

 private:
  // Devices have a handful of PDOs; past 63 they share a bit, which only publishes earlier.
  static std::uint64_t bit(std::size_t index) { return std::uint64_t{1} << std::min<std::size_t>(index, 63); }

  canopen::BusLoop& loop_;
  std::function<void(std::int64_t)> publish_;
  canopen::BusLoop::FlushId flush_;
  std::uint64_t waiting_ = 0;  // a bit per PDO index decoded since the last sample
  std::int64_t stamp_ns_ = 0;
};

}  // namespace lb::gateways
