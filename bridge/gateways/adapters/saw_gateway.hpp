#pragma once
// CiA 420-4 saw on DDS: decodes its TPDOs into rt/<line>/<device>/status (and a cut event per
// cut), validates set values from rt/<line>/<device>/setpoint and sends them in RPDO1 at every
// SYNC (master role), or decodes the line controller's RPDO1 (monitor role).

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "base/shared_log_rate.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "gateways/adapters/gateway.hpp"
#include "gateways/codecs/saw_codec.hpp"
#include "gateways/commands/command_service.hpp"
#include "gateways/node/device_output.hpp"
#include "gateways/node/pdo_burst.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"

namespace lb::gateways {

class SawGateway : public Gateway {
 public:
  // Throws std::runtime_error at start-up when the profile lacks what a saw needs.
  explicit SawGateway(DeviceContext context);

  const CommandService* commands() const override { return &command_service_; }

  // NodeDriver: what the node hears (both roles). The SYNC and the RPDOs are the output's.
  void on_nmt_change(canopen::NmtState state, bool online) noexcept override;
  void on_emcy(const canopen::Emergency& e) noexcept override { publish_status(e.timestamp_ns); }
  void on_errors() noexcept override { publish_status(ddsl::now_ns()); }

 private:
  void on_pdo(std::size_t pdo, const can::CanFrame& frame);

  void on_setpoint(const linebridge_msgs::msg::SawSetpoint& sp);
  void publish_status(std::int64_t stamp_ns);
  void reply(std::uint64_t request_id, bool accepted, const std::string& reason);

  DeviceContext ctx_;
  SharedLogRate set_value_log_;  // refusals, from DDS threads and the loop
  LogRate applied_log_;          // set values taken, on the loop
  SawCodec codec_;               // loop thread, except validate() (const, any thread)
  PdoBurst burst_;
  DeviceOutput<SawCodec> output_;   // the RPDO image and what of it goes out
  CommandService command_service_;  // presses through output_

  ddsl::Writer<linebridge_msgs::msg::SawStatusPubSubType> status_writer_;
  ddsl::Writer<linebridge_msgs::msg::SawCutPubSubType> cut_writer_;
  ddsl::Writer<linebridge_msgs::msg::SetpointResultPubSubType> result_writer_;

  // Loop-thread state.
  linebridge_msgs::msg::SawStatus status_;
  bool was_cutting_ = false;
  bool program_was_on_ = false;
  double counter_before_cut_m_ = 0;
  double length_in_force_m_ = 0;  // the set value the saw's comparator uses (6020h bit 2 semantics)
  std::uint32_t cut_count_ = 0;
};

}  // namespace lb::gateways
