#pragma once
// Keeps one device's hold across restarts of the bridge (master role). It hears every change of
// the node's hold (NodeDriver::on_hold: an operator's NMT stop or pre-operational, their start or
// reset, the line's stop_others) and records in the store who holds the device, why and since
// when; at start-up, before the loop runs, it puts the kept hold back on the node, so that the
// first boot configures the device and puts it back in the held state instead of starting it
// (BootSequence keeps RemoteNode::operator_hold; a device found operational is stopped by it).
//
// Who holds it is settled once the command that changed it has been handled: a hold and its
// owner change in two steps (the node's hold, then MandatoryDevices' status or the operator's
// listeners), so the record is taken in a task posted from on_hold, when both agree. The line's
// waiting hold ("waiting for mandatory device X") is no decision and is never kept: every start
// decides it anew.
//
// Everything runs on the bus's loop thread but the constructor and restore() (before it starts).

#include <functional>
#include <optional>
#include <string>

#include "canopen/bus_loop.hpp"
#include "canopen/node_driver.hpp"
#include "canopen/remote_node.hpp"
#include "gateways/persistence/kept_holds.hpp"
#include "gateways/persistence/set_value_store.hpp"

namespace lb::gateways {

class HoldKeeper final : public canopen::NodeDriver {
 public:
  // What the line (MandatoryDevices) holds the device in, as far as it is concerned.
  struct LineHold {
    enum class Kind { none, waiting, stopped };
    Kind kind = Kind::none;
    std::string reason;  // stopped: the mandatory device and what happened to it
  };
  using LineView = std::function<LineHold()>;

  // Before the loop starts: attaches to the node.
  HoldKeeper(canopen::BusLoop& loop, canopen::RemoteNode& node, SetValueStore& store, KeptHold::Key key,
             std::string device);
  HoldKeeper(const HoldKeeper&) = delete;
  HoldKeeper& operator=(const HoldKeeper&) = delete;
  ~HoldKeeper() = default;

  // Before the loop starts, after every other driver of the node is attached (they hear the hold
  // as any other): puts the hold the file kept for this device back on the node and returns it
  // (a line's stop is also the line's to know: MandatoryDevices::kept_stop).
  std::optional<KeptHold> restore();
  // Before the loop starts: the line's view of the device (a bus with mandatory devices).
  void set_line_view(LineView view) { line_view_ = std::move(view); }
  // Loop thread: an operator's NMT command went to the device (DeviceServices' listener). From
  // then on a stop or pre-operational on it is the operator's.
  void operator_command(canopen::NmtCommand command);

  // Loop thread, for diagnostics: the hold in force and, when it is the one kept from before the
  // restart, that it is ("" when there is none).
  std::string note() const;
  // Loop thread: the hold as recorded now.
  const std::optional<KeptHold>& kept() const { return kept_; }

  void on_hold(const std::optional<canopen::NmtCommand>& hold) noexcept override;

 private:
  void settle();  // records who holds the device now
  std::optional<KeptHold> holder_now() const;

  canopen::BusLoop& loop_;
  canopen::RemoteNode& node_;
  SetValueStore& store_;
  KeptHold::Key key_;
  std::string device_;
  LineView line_view_;
  std::optional<KeptHold> kept_;  // what the store holds for the device
  bool from_before_ = false;      // kept_ is the hold restored at start-up, unchanged since
  bool by_operator_ = false;      // an operator's command came since the hold was restored
  bool settle_posted_ = false;
};

}  // namespace lb::gateways
