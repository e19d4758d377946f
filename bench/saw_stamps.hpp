#pragma once
// Send times carried through the saw's own objects (CiA 420-4 TPDOs, default mapping), so the
// receiving process can time every sample without a side channel:
//   frame k (1, 2, ...) of a device is TPDO1 when k is odd: 6030h status word = saw ready,
//     6000h counter value = send stamp;
//   and TPDO2 when k is even: 6001h actual saw counter = send stamp, 6007h product speed = k.
// In the status sample a TPDO2 shows as a new product speed and a TPDO1 as a new counter value;
// the bare DDS writer of the floor fills its samples exactly as the bridge decodes these frames.

#include <array>
#include <cmath>
#include <cstdint>
#include <optional>

#include "can/can_frame.hpp"
#include "msgs/saw.h"

namespace lb::bench {

constexpr std::uint32_t kTpdo1Base = 0x180;
constexpr std::uint32_t kTpdo2Base = 0x280;
constexpr std::uint16_t kStatusWordReady = 0x0001;  // 6030h bit 0; no cut bit: no cut events
// Profile scales (cia420-4 3.1): 6001h 0.1 mm -> m, 6007h mm/min -> m/min.
constexpr double kSawCounterScale = 0.0001;
constexpr double kSpeedScale = 0.001;

inline void put_le(std::uint8_t* p, std::uint32_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
inline std::uint32_t get_le32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 | std::uint32_t{p[3]} << 24;
}

inline can::CanFrame saw_tpdo(std::uint8_t node, std::uint32_t k, std::uint32_t stamp) {
  can::CanFrame f;
  if (k % 2 == 1) {
    f.id = kTpdo1Base + node;
    f.len = 6;
    put_le(&f.data[0], kStatusWordReady, 2);
    put_le(&f.data[2], stamp, 4);
  } else {
    f.id = kTpdo2Base + node;
    f.len = 8;
    put_le(&f.data[0], stamp, 4);
    put_le(&f.data[4], k, 4);
  }
  return f;
}

// The send stamp of a frame built by saw_tpdo (for the bare bus hop).
inline std::optional<std::uint32_t> frame_stamp(const can::CanFrame& f) {
  if (f.error || f.rtr || f.extended) return std::nullopt;
  if (f.id > kTpdo1Base && f.id < kTpdo1Base + 0x80 && f.len == 6) return get_le32(&f.data[2]);
  if (f.id > kTpdo2Base && f.id < kTpdo2Base + 0x80 && f.len == 8) return get_le32(&f.data[0]);
  return std::nullopt;
}

// What the bridge's decoding of frame k does to a status sample (for the bare DDS writer).
inline void apply_tpdo(linebridge_msgs::msg::SawStatus& s, std::uint32_t k, std::uint32_t stamp) {
  if (k % 2 == 1) {
    s.status_word().raw(kStatusWordReady);
    s.status_word().saw_ready(true);
    s.counter_value(stamp);
  } else {
    s.actual_saw_counter_m(static_cast<double>(static_cast<std::int32_t>(stamp)) * kSawCounterScale);
    s.product_speed_m_per_min(static_cast<double>(static_cast<std::int32_t>(k)) * kSpeedScale);
  }
}

// Per device, on the receiving side: which frames a status sample reflects, and their send stamps.
// The bridge may merge a device's TPDO1 and TPDO2 into one sample (a burst, see PdoBurst), so a
// sample reflects up to two frames; samples that reflect no new frame (the bridge's initial sample,
// NMT or EMCY changes) give none. A frame whose values never show (overwritten before they were
// published) is never counted, so it shows as missing.
class StampDecoder {
 public:
  struct Hit {
    std::uint32_t stamp;
    bool tpdo2;
    std::uint32_t k;  // TPDO2 only
  };
  struct Hits {
    std::array<Hit, 2> hit{};
    int n = 0;
  };

  Hits next(const linebridge_msgs::msg::SawStatus& s) {
    Hits h;
    const auto k = static_cast<std::uint32_t>(std::llround(s.product_speed_m_per_min() / kSpeedScale));
    if (k != last_k_) {
      last_k_ = k;
      const auto raw = static_cast<std::int32_t>(std::llround(s.actual_saw_counter_m() / kSawCounterScale));
      h.hit[static_cast<std::size_t>(h.n++)] = Hit{static_cast<std::uint32_t>(raw), true, k};
    }
    if (s.counter_value() != last_counter_) {
      last_counter_ = s.counter_value();
      h.hit[static_cast<std::size_t>(h.n++)] = Hit{last_counter_, false, 0};
    }
    return h;
  }

 private:
  std::uint32_t last_k_ = 0;
  std::uint32_t last_counter_ = 0;
};

}  // namespace lb::bench
