#pragma once
// What a SocketCAN error frame says about the controller: its state (error-active, -warning,
// -passive, bus-off), its error counters and overflows, folded into BusStats. Shared by every bus
// that sees real error frames (SocketCAN, and a replayed recording of one).

#include "can/bus.hpp"
#include "can/can_frame.hpp"

namespace lb::can {

// frame must be an error frame (frame.error): id holds the error class bits, data the details, as
// <linux/can/error.h> defines them. Frames that say nothing about the state leave it unchanged.
void apply_error_frame(const CanFrame& frame, BusStats& stats);

}  // namespace lb::can
