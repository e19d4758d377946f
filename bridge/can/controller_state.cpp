#include "can/controller_state.hpp"

#include <linux/can/error.h>

namespace lb::can {

void apply_error_frame(const CanFrame& frame, BusStats& stats) {
  if (!frame.error) return;
  const std::uint32_t cls = frame.id;
  const std::uint8_t ctrl = frame.len > 1 ? frame.data[1] : 0;

  if ((cls & CAN_ERR_CNT) != 0 && frame.len >= 8) {
    stats.tx_error_counter = frame.data[6];
    stats.rx_error_counter = frame.data[7];
  }
  if ((cls & CAN_ERR_CRTL) != 0 && (ctrl & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) != 0) {
    ++stats.rx_overflows;
  }

  // The kernel reports a state change with the new state's bits, downwards as well as upwards, so
  // the frame's worst state is the new one. Bus-off wins over whatever else the frame carries.
  if ((cls & CAN_ERR_BUSOFF) != 0) {
    if (stats.state != BusState::bus_off) ++stats.bus_offs;
    stats.state = BusState::bus_off;
    return;
  }
  if ((cls & CAN_ERR_CRTL) != 0) {
    if ((ctrl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0) {
      stats.state = BusState::error_passive;
      return;
    }
    if ((ctrl & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0) {
      stats.state = BusState::error_warning;
      return;
    }
    if ((ctrl & CAN_ERR_CRTL_ACTIVE) != 0) {
      stats.state = BusState::error_active;
      return;
    }
  }
  // After bus-off the controller comes back error-active (restart-ms or `ip link ... restart`).
  if ((cls & CAN_ERR_RESTARTED) != 0) stats.state = BusState::error_active;
}

}  // namespace lb::can
