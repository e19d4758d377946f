#pragma once
// CiA 414-2 feeder control box on DDS (contract: docs/devices/feeder.md).
//   CAN -> DDS: rt/<line>/<device>/status (per feeder 6009h, 6007h, 6001h polled by SDO in the master
//   role; the FF10h bitmap; 6008h; the loom side of the bus), an `unwinding` event per TPDO1 and a
//   `feeder_error` event per change of a feeder in EMCY FF10h, with 6007h read by SDO at once.
//   DDS -> CAN (master role only): typed configuration services (600Eh, 600Fh, 6001h, 6011h/6012h,
//   6002h, 6005h) as checked SDO writes, and `loom` set values sent in the loom controller's
//   event-driven RPDOs. The bridge drives those RPDOs only after the first accepted `loom` set value:
//   normally the loom controller does, and only one may drive a bus.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "base/shared_log_rate.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "gateways/adapters/gateway.hpp"
#include "gateways/codecs/feeder_codec.hpp"
#include "gateways/node/device_output.hpp"
#include "gateways/node/pdo_burst.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/feederPubSubTypes.h"

namespace lb::gateways {

class FeederGateway : public Gateway {
 public:
  // Throws std::runtime_error at start-up when the profile lacks what a feeder needs.
  explicit FeederGateway(DeviceContext context);

  // NodeDriver: what the node hears (both roles). The RPDOs are the output's.
  void on_nmt_change(canopen::NmtState state, bool online) noexcept override;
  void on_emcy(const canopen::Emergency& e) noexcept override;
  void on_errors() noexcept override { publish_status(ddsl::now_ns()); }

 private:
  using WriteReply = std::function<void(linebridge_msgs::srv::FeederWrite_Response)>;
  // One SDO read of a poll; value is nullopt when the device refused or did not answer.
  struct Read {
    std::uint16_t index;
    std::uint8_t sub;
    // May add reads that follow (the per-feeder reads once the count is known).
    std::function<void(std::optional<std::uint64_t> value, std::vector<Read>& more)> apply;
  };

  void on_pdo(std::size_t pdo, const can::CanFrame& frame);
  void poll();
  void read_chain(const std::shared_ptr<std::vector<Read>>& reads, std::size_t next);
  void publish_error_event(unsigned feeder, bool in_error, std::uint32_t bitmap, std::int64_t stamp_ns);
  void publish_status(std::int64_t stamp_ns);
  linebridge_msgs::msg::FeederEntry& entry(unsigned feeder);

  void serve_services();
  template <class RequestPS>
  // stops: which requests stop a feeder (they run whatever run of the bridge they name).
  void serve(const std::string& name, std::function<void(const typename RequestPS::type&, WriteReply)> handler,
             std::function<bool(const typename RequestPS::type&)> stops = {});
  // Validated on the DDS thread; empty when the bus takes commands.
  std::string refusal() const;
  std::optional<unsigned> feeder_count() const;
  // A checked write, once the box can answer SDO (sdo_admission.hpp); then() instead of the reply
  // when it succeeded (a second write follows). write_now: already admitted.
  // stop: a command that takes a feeder out of operation, sent whenever the box is heard.
  void write(const FeederCodec::Write& w, const WriteReply& reply, std::function<void()> then = {}, bool stop = false);
  void write_now(const FeederCodec::Write& w, WriteReply reply, std::function<void()> then = {}, bool stop = false);
  void when_sdo_possible(const WriteReply& reply, std::function<void()> send, bool stop = false);
  void read(std::uint16_t index, std::uint8_t sub, canopen::SdoClient::ReadDone done,
            std::optional<canopen::SdoClient::Limit> limit = std::nullopt);

  void on_loom(const linebridge_msgs::msg::LoomSetpoint& sp);
  void loom_reply(std::uint64_t request_id, bool accepted, const std::string& reason);
  // Loop thread: the box's RPDO3 (600Dh digital outputs, optional) is in use.
  bool outputs_in_use();

  DeviceContext ctx_;
  SharedLogRate refusal_log_;  // refused writes and loom set values, from DDS threads and the loop
  FeederCodec codec_;          // loop thread, except the const validation (any thread)
  PdoBurst burst_;
  // The loom controller's RPDOs: silent until the first loom set value of this run (a loom
  // controller normally drives them, and only one may drive a bus).
  DeviceOutput<FeederCodec> output_;

  ddsl::Writer<linebridge_msgs::msg::FeederStatusPubSubType> status_writer_;
  ddsl::Writer<linebridge_msgs::msg::FeederUnwindingPubSubType> unwinding_writer_;
  ddsl::Writer<linebridge_msgs::msg::FeederErrorPubSubType> error_writer_;
  ddsl::Writer<linebridge_msgs::msg::SetpointResultPubSubType> loom_result_writer_;

  std::atomic<int> feeder_count_{-1};  // 6009h sub 0 as last read; -1 unknown (DDS threads read it)

  // Loop-thread state.
  canopen::BusLoop::TimerId poll_timer_{};
  bool polling_ = false;
  bool loom_played_ = false;  // a loom set value was taken in this run (logged once)
  std::uint32_t bitmap_ = 0;
  // Feeders whose 6007h detail read is queued or under way (loop thread): one read per feeder at
  // a time, so a chattering FF10h bit cannot grow the node's SDO queue (at most 32 reads wait);
  // the events in between are published without the detail, and counted.
  std::uint32_t detail_pending_ = 0;
  std::uint64_t detail_reads_coalesced_ = 0;
  linebridge_msgs::msg::FeederStatus status_;
};

}  // namespace lb::gateways
