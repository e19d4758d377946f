#pragma once
// What every device offers on DDS whatever its profile: its emergencies and its identity (info)
// on its own topics, and the work behind the nmt, sdo_read, sdo_write, get_parameter and
// set_parameter services (the last two: profile objects by name, in engineering units, checked
// against the profile's access and range). Those services are line-wide (ManagementServices
// serves them once per bridge and hands each request to the named device's handler here): a
// Fast DDS endpoint pair per service and device would cost ~40 KiB each. In the master role it
// also owns the device's node state machine (boot, error control, NMT: canopen/node_state_machine).
// Device-type gateways add status, set values and typed configuration.

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "canopen/boot_sequence.hpp"
#include "canopen/error_field.hpp"
#include "canopen/node_driver.hpp"
#include "canopen/node_state_machine.hpp"
#include "dds/service.hpp"
#include "gateways/node/device_context.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

class DeviceServices final : public canopen::NodeDriver {
 public:
  // Throws std::runtime_error at start-up when a topic cannot be created.
  explicit DeviceServices(DeviceContext context);
  DeviceServices(const DeviceServices&) = delete;
  DeviceServices& operator=(const DeviceServices&) = delete;

  // Loop thread: the first boot (master role).
  void start();
  // Loop thread, instead of start() on a standby that took the bus over (NodeStateMachine::take_over).
  void take_over(std::optional<canopen::NmtCommand> last_command);
  // Before the loop starts: told (loop thread) every NMT command an operator's request sent (the
  // line-level mandatory-device policy listens).
  void on_operator_nmt(std::function<void(canopen::NmtCommand)> listener) {
    nmt_listeners_.push_back(std::move(listener));
  }
  // Loop thread: a boot is checking and configuring the device right now (master role).
  bool booting() const { return state() == canopen::NodeState::booting; }
  // Loop thread: the node state machine's state (master role; nullopt: monitored).
  std::optional<canopen::NodeState> state() const {
    return machine_ ? std::optional<canopen::NodeState>(machine_->state()) : std::nullopt;
  }
  // Loop thread: "started", "failed (K): ...", a pending retry, "monitored" (monitor role).
  std::string boot_state() const { return machine_ ? machine_->detail() : "monitored"; }
  std::string_view node_state() const { return machine_ ? canopen::to_string(machine_->state()) : "monitored"; }
  // Loop thread: the last boot failed after the device answered SDO (not a device that is silent).
  bool answered_boot() const {
    return report_.error.has_value() && !(report_.error->code == 'B' && report_.error->abort_code == 0x05040000u);
  }
  // Loop thread: what the last finished boot found (empty before the first one).
  const canopen::BootReport& boot_report() const { return report_; }
  canopen::NodeStateMachine::Counters boot_counters() const {
    return machine_ ? machine_->counters() : canopen::NodeStateMachine::Counters{};
  }

  // NodeDriver.
  void on_emcy(const canopen::Emergency& e) noexcept override;
  // Service requests still waiting for a device that went offline could only time out one
  // after the other: they are answered at once.
  void on_nmt_change(canopen::NmtState state, bool online) noexcept override;
  // After every boot attempt, and after the reading of a device adopted at a takeover (master role).
  void on_boot(const canopen::BootReport& report) noexcept override { booted(report); }

  // This device's part of the line-wide services; the request's `device` is already this one.
  // Called on a Fast DDS thread; checks what needs only the immutable profile and configuration
  // there and answers at once, or answers later from the bus loop thread (NMT sent, SDO done).
  void nmt(const linebridge_msgs::srv::Nmt_Request& request,
           const ddsl::Respond<linebridge_msgs::srv::Nmt_Response>& respond);
  void sdo_read(const linebridge_msgs::srv::SdoRead_Request& request,
                const ddsl::Respond<linebridge_msgs::srv::SdoRead_Response>& respond);
  void sdo_write(const linebridge_msgs::srv::SdoWrite_Request& request,
                 const ddsl::Respond<linebridge_msgs::srv::SdoWrite_Response>& respond);
  void get_parameter(const linebridge_msgs::srv::GetParameter_Request& request,
                     const ddsl::Respond<linebridge_msgs::srv::GetParameter_Response>& respond);
  void set_parameter(const linebridge_msgs::srv::SetParameter_Request& request,
                     const ddsl::Respond<linebridge_msgs::srv::SetParameter_Response>& respond);

 private:
  std::string refusal() const;  // why this bus takes no commands, or empty
  // Master role, after a boot that passed: 1001h reconciles the node's active errors, 1003h is
  // kept as the error history for info; then 6010h and info.
  void read_errors();
  // Master role: an EMCY came while the device was operational. Its own 1001h is read again, so an
  // EMCY it never sent (CAN is not authenticated) is cleared when its register says 00h: one read
  // at a time per device, at most one a second, through the SDO client's queue, from a timer
  // (never in the frame's handler).
  void check_errors_after_emcy();
  bool errors_to_check() const;  // operational, its boot passed, and the list has codes or is uncertain
  void read_register_after_emcy();
  void read_configuration_word_and_publish();
  void booted(const canopen::BootReport& report);
  void publish_info();
  // 6010h, from a read (nullopt: failed, with the reason) or "not read".
  void set_configuration_word(std::optional<std::uint64_t> raw, const std::string& remark);

  DeviceContext ctx_;
  ddsl::Writer<linebridge_msgs::msg::EmergencyPubSubType> emergency_writer_;
  ddsl::Writer<linebridge_msgs::msg::DeviceInfoPubSubType> info_writer_;
  std::unique_ptr<canopen::NodeStateMachine> machine_;    // master role
  const profiles::BitSet* configuration_bits_ = nullptr;  // 6010h's named bits; null: the profile has none
  // Loop thread.
  canopen::BootReport report_;
  std::uint64_t boots_reported_ = 0;  // a newer boot report outdates the reads of an older one
  bool reading_errors_ = false;
  bool reread_errors_ = false;
  // The 1001h check after an EMCY (check_errors_after_emcy).
  canopen::BusLoop::TimerId error_check_timer_{};
  bool error_check_armed_ = false;
  bool error_check_in_flight_ = false;
  bool error_check_again_ = false;  // an EMCY came while the read was in flight: its answer may predate it
  std::chrono::steady_clock::time_point error_check_at_{};  // the last one's start
  linebridge_msgs::msg::ConfigurationWord configuration_word_;
  canopen::ErrorHistory error_history_;  // 1003h as the last boot that passed read it
  std::vector<std::function<void(canopen::NmtCommand)>> nmt_listeners_;
};

// The boot's findings as their DDS types.
linebridge_msgs::msg::BootError to_msg(const canopen::BootError& error);
linebridge_msgs::msg::PdoInfo to_msg(const canopen::PdoInUse& pdo);

}  // namespace lb::gateways
