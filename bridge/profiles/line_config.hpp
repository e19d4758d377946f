#pragma once
// One YAML file describes a line: DDS settings, buses and devices. Loading validates everything
// (keys, ranges, references, profiles) so nothing starts half-configured.

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "canopen/object_value.hpp"
#include "canopen/pdo_parameters.hpp"
#include "profiles/profile_registry.hpp"

namespace lb::profiles {

// master: the NMT master and SYNC producer. standby: a redundant master (docs/redundancy.md) that
// listens while another master's heartbeat (master_node_id) is heard and takes the bus over,
// without a reset, when it stops. monitor: listen-only.
enum class BusRole { master, monitor, standby };
std::string_view to_string(BusRole role);
// The roles that master the bus (a standby once it took over): they hold a device's output.
constexpr bool masters(BusRole role) { return role != BusRole::monitor; }

// dds.security: the files of the bridge's own identity (paths made absolute, relative ones taken
// from the line file's folder) and extra Fast DDS security properties.
struct DdsSecurityConfig {
  std::string identity_ca;
  std::string certificate;
  std::string private_key;
  std::string permissions_ca;
  std::string governance;
  std::string permissions;
  std::vector<std::pair<std::string, std::string>> properties;
  std::string identity_crl;  // optional: the identity CA's revocation list; empty: none
};

// dds.discovery_servers: a Fast DDS discovery server (fast-discovery-server -i id -l address -p port).
struct DdsDiscoveryServer {
  std::uint8_t id = 0;
  std::string address;  // IPv4
  std::uint16_t port = 11811;
};

struct DdsConfig {
  std::uint32_t domain = 0;
  bool localhost_only = true;
  std::optional<DdsSecurityConfig> security;          // absent: an unsecured domain
  std::string profiles_file;                          // Fast DDS XML profiles (absolute path); "" = none
  std::string participant_profile;                    // a participant profile of it by name; "" = its default one
  std::vector<DdsDiscoveryServer> discovery_servers;  // none: simple (multicast) discovery
  bool shared_memory = false;                         // Fast DDS's shared-memory transport besides UDP (one user only)
  // Remote participants let in at once that have not proven themselves yet (authenticated, on a
  // secured line): what forged announcements can make the DDS process hold (dds/discovery_gate.hpp).
  int max_pending_participants = 32;
};

// observability: the DDS process's read-only status page and metrics (docs/observability.md). On
// loopback unless the line file names another address; `listen: off` serves nothing.
struct ObservabilityConfig {
  bool enabled = true;
  std::string address = "127.0.0.1";  // numeric IPv4, or IPv6 (without brackets)
  std::uint16_t port = 9420;

  bool ipv6() const { return address.find(':') != std::string::npos; }
  // As civetweb's listening_ports and a URL spell it: 127.0.0.1:9420, [::1]:9420.
  std::string listen() const { return (ipv6() ? "[" + address + "]" : address) + ":" + std::to_string(port); }
};

struct BusConfig {
  std::string name;
  std::string interface;  // "socketcan:can0", "virtual:demo", "log:/path/file.log?pace=fast"
  std::string record;     // candump -l format file every frame of the bus is appended to; "" = none
  BusRole role = BusRole::master;
  std::chrono::microseconds sync_period{20'000};  // CiA 420-1: 20 ms
  std::uint32_t bitrate = 500'000;                // bit/s, for the bus load in diagnostics
  std::uint8_t master_node_id = 0;                // the bridge's own heartbeat (master role); 0 = none
  std::chrono::milliseconds master_heartbeat_period{1000};
  // Standby role: the master's heartbeat (master_node_id) silent this long, the standby takes over.
  // Each bridge of a pair has its own, so that two started together end with one master.
  std::chrono::milliseconds takeover_after{0};
  // Standby role: CiA 302-2 flying-master negotiation (1F90h; docs/redundancy.md). The bridge's node-ID
  // in it is master_node_id, which both bridges of a pair share: their priorities must differ.
  struct FlyingMaster {
    std::uint8_t priority = 0;                         // sub 3: lower wins (71h carries one byte)
    std::chrono::milliseconds detect_timeout{100};     // sub 1: the wait for a 71h after 73h
    std::chrono::milliseconds negotiation_delay{500};  // sub 2: listening before 73h at power-up
    std::chrono::milliseconds priority_slot{1500};     // sub 4
    std::chrono::milliseconds device_slot{10};         // sub 5
    std::chrono::milliseconds detect_cycle{4000};      // sub 6: the active master's 76h
  };
  FlyingMaster flying;
  std::chrono::milliseconds sdo_timeout{1000};
  // Master role: another master heard on the bus (canopen/other_master.hpp): yield = transmit
  // nothing while it is there; warn = report and go on.
  bool yield_to_other_master = true;
  // The bus loop thread's SCHED_FIFO priority, 1..99 (canopen/bus_loop.hpp); 0 = normal scheduling.
  int realtime_priority = 0;
};

// Identity values (1000h device type, 1018h sub 1..4). Expected ones, in a device's configuration:
// each given value is checked at every boot (CiA 302-2 1F84h..1F88h), the rest are not.
struct Identity {
  std::optional<std::uint32_t> device_type;
  std::optional<std::uint32_t> vendor_id;
  std::optional<std::uint32_t> product_code;
  std::optional<std::uint32_t> revision;
  std::optional<std::uint32_t> serial_number;
};

// A simulated device's own PDO defaults where they differ from its profile's (its "factory"
// configuration): what a master finds before it writes anything.
struct SimulatedPdo {
  std::string name;
  std::optional<std::uint32_t> cob_id;  // the full CiA 301 entry
  std::optional<std::uint8_t> transmission_type;
  std::optional<std::uint16_t> inhibit_time_100us;
  std::optional<std::uint16_t> event_timer_ms;
  std::optional<std::vector<canopen::PdoEntry>> mapping;  // any objects: the simulator checks them
};

// Only read by linebridge-sim: how the simulated device behaves.
struct SimulationConfig {
  double max_speed_m_per_min = 30.0;       // line speed at 100 % sync speed
  double acceleration_m_per_min_s = 60.0;  // speed ramp
  std::uint32_t scaling_pulses_per_m = 10'000;
  std::chrono::milliseconds heartbeat_period{100};
  // What linebridge-sim sends this device when it plays the line controller (--role controller):
  // raw values of the device's RPDO objects by profile object name; others are sent as 0.
  std::vector<std::pair<std::string, std::uint64_t>> controller_values;
  // What the device answers in 1000h and 1018h instead of the simulator's own values.
  Identity identity;
  std::vector<SimulatedPdo> pdos;
  // Objects (index << 8 | sub) whose SDO writes the device confirms and then ignores, as a faulty
  // device may: a master that reads back notices.
  std::vector<std::uint32_t> ignore_writes;
  // CiA 301 1003h (pre-defined error field): the device's error history (every EMCY it sent,
  // newest first). false: it has no 1003h, as many devices (the object is optional).
  bool pre_defined_error_field = true;
  // false: the boot-up message after an NMT reset is lost (a fault to test a master with; the
  // power-on boot-up is still sent).
  bool boot_up_after_nmt_reset = true;
  // How long an NMT reset node / reset communication takes before the boot-up; the device is
  // silent meanwhile (a real device may take seconds to restart).
  std::chrono::milliseconds reset_time{0};
};

// One SDO write of a device's boot configuration (written in this order before NMT start).
struct SdoWrite {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  canopen::DataType type = canopen::DataType::unsigned8;
  canopen::ObjectValue value;
  std::string text;    // as written in the file, for logs
  bool verify = true;  // read back after writing (false: write-only objects, or `verify: false`)
};

// A PDO as one device uses it: the profile's default with the line configuration's overrides.
struct DevicePdo {
  std::string name;  // tpdo1, rpdo1, ...
  PdoDirection direction = PdoDirection::tx;
  std::uint32_t can_id = 0;  // the identifier on the bus (node-ID included)
  bool extended = false;     // 29-bit identifier (COB-ID bit 29)
  bool enabled = true;       // COB-ID bit 31 clear
  std::uint8_t transmission_type = 1;
  std::chrono::microseconds inhibit{0};      // event-driven: minimum gap between two transmissions
  std::chrono::milliseconds event_timer{0};  // event-driven: resend at least this often (0 = never)
  std::vector<canopen::PdoEntry> mapping;

  // False where the profile lets a device start with the PDO valid or not (COB-ID bit 31: feeder
  // TPDO1) and the line configuration does not say: then the device's choice is taken as it is.
  bool validity_given = true;

  bool synchronous() const { return transmission_type <= 240; }
  bool event_driven() const { return transmission_type >= 254; }
  // The 32-bit COB-ID entry (1400h/1800h sub 1) as CiA 301 writes it.
  std::uint32_t cob_id_entry() const { return (enabled ? 0U : 0x8000'0000U) | (extended ? 0x2000'0000U : 0U) | can_id; }
};

// The profile's PDOs as a device at node_id has them before any override.
std::vector<DevicePdo> default_pdos(const Profile& profile, std::uint8_t node_id);

// How the bridge treats a device's PDO parameters at boot.
enum class PdoConfigMode {
  configure,  // make the device match the line (profile defaults + overrides), or refuse to start it
  adopt,      // take the device's PDO parameters as they are and decode and send by them
};
std::string_view to_string(PdoConfigMode mode);

// What the bridge does when it no longer knows what a device's object dictionary holds (its
// heartbeat came back after a loss, or it reports pre-operational or stopped unasked).
enum class StateUnknownAction {
  reboot,      // run the whole boot again (identity, configuration, start)
  reset_node,  // NMT reset node: the device restarts and its boot-up starts the boot
};
std::string_view to_string(StateUnknownAction action);

// What a device gets back of the set values in force when the bridge starts it (README: "Start-up
// and recovery"). A device found operational kept running without the bridge (only the bridge or
// the line PC restarted): continuity, everything is restored. A device found pre-operational or
// freshly booted lost power or was reset: IEC 60204-1 7.5, it must not restart by itself, so its
// enabling levels (marked `enabling` in the profiles) stay off until an operator sets them again.
struct StartupPolicy {
  enum class AfterPowerLoss { non_enabling, nothing };
  enum class Restart { never, allowed };
  // Kept set values last held in force longer ago than this are not restored at all.
  std::chrono::seconds set_values_max_age{3600};
  // What a device found not operational gets: speeds, lengths and modes (non_enabling), or zero.
  AfterPowerLoss after_power_loss = AfterPowerLoss::non_enabling;
  // allowed: its enabling levels too (the integrator has judged an automatic restart safe).
  Restart restart_after_power_loss = Restart::never;
  // What a master bus does when one of its mandatory devices (DeviceConfig::mandatory, the CiA
  // 302-2 1F81h bit 3 idea) is lost or fails its boot while the line runs: stop every other
  // device the bridge started and keep it stopped until an operator starts it (CiA 302-2 1F80h
  // bit 6 "stop all"), or only report it. Either way no device of the bus is started at start-up
  // before every mandatory one passed its boot.
  enum class WhenMandatoryFails { stop_others, report_only };
  WhenMandatoryFails when_mandatory_fails = WhenMandatoryFails::stop_others;
  // A device found operational whose PDO parameters must change (CiA 301 lets it refuse them
  // while a PDO is valid): pre_operational (NMT enter pre-operational, write, read back, start) or
  // keep_running (not written; boot error J once, left running unmanaged).
  canopen::PdoChangeWhenRunning pdo_change_when_running = canopen::PdoChangeWhenRunning::pre_operational;
};
std::string_view to_string(StartupPolicy::WhenMandatoryFails policy);

struct DeviceConfig {
  std::string name;
  std::string bus;
  std::uint8_t node_id = 0;
  std::string profile;
  std::string version;
  std::chrono::milliseconds heartbeat_timeout{500};
  std::vector<SdoWrite> configure;             // boot configuration (master role)
  std::vector<DevicePdo> pdos;                 // the profile's PDOs with this device's overrides
  std::chrono::milliseconds boot_retry{5000};  // a device that does not answer is tried again
  Identity identity;                           // expected identity, checked at every boot
  PdoConfigMode pdo_config = PdoConfigMode::configure;
  StateUnknownAction on_state_unknown = StateUnknownAction::reboot;
  // Written to 1017h at every boot, after `configure`; nullopt: the device's own value is kept.
  std::optional<std::chrono::milliseconds> heartbeat_producer;
  // The device enters operational by itself at power-on (no NMT master needed): finding it
  // operational then proves nothing about a power loss, so it is treated as freshly booted.
  bool starts_itself = false;
  // Master role: the line does not run without it (CiA 302-2 1F81h bit 3, off by default): no
  // device of its bus is started before it passed its boot, and its loss or a failed boot while
  // the line runs is handled by StartupPolicy::when_mandatory_fails.
  bool mandatory = false;
  SimulationConfig simulation;
  const Profile* resolved_profile = nullptr;  // points into the registry the config was loaded with
  // The profile with the device's `objects:` (manufacturer-specific objects the line names), or
  // null when it names none. The bridge decodes by bridge_profile(); a simulator by its profile.
  std::shared_ptr<const Profile> profile_with_objects;

  const Profile& bridge_profile() const { return profile_with_objects ? *profile_with_objects : *resolved_profile; }
};

// When a device's status sample goes out (docs/dds-contract.md, gateways/node/pdo_burst.hpp).
enum class StatusPublish {
  per_cycle,  // once the device's synchronous TPDOs of a SYNC cycle are in (or when the cycle ends)
  per_frame,  // per burst of PDOs, as they are read
};
std::string_view to_string(StatusPublish p);

struct LineConfig {
  std::string line;
  DdsConfig dds;
  StatusPublish status_publish = StatusPublish::per_cycle;
  // Where the set values in force are kept across restarts (<state_dir>/<line>.set_values); empty:
  // $STATE_DIRECTORY (systemd's StateDirectory=) when set, else nowhere. restore_set_values false:
  // every start begins from zero (and still keeps them).
  std::string state_dir;
  bool restore_set_values = true;
  StartupPolicy startup;
  ObservabilityConfig observability;
  std::vector<BusConfig> buses;
  std::vector<DeviceConfig> devices;
  // profiles_dir: profile files loaded over the built-in ones; the devices' resolved_profile
  // point into `profiles` then (shared, so copies of the configuration stay valid).
  std::string profiles_dir;
  std::shared_ptr<const ProfileRegistry> profiles;
  // What start-up accepts but an integrator should look at ("file:line:column: ..."), for --check.
  std::vector<std::string> warnings;

  const BusConfig* bus(std::string_view name) const;
  const DeviceConfig* device(std::string_view name) const;
};

// `source` names the text in error messages (the file path). The registry must outlive the result.
Result<LineConfig> parse_line_config(const std::string& yaml_text, const std::string& source,
                                     const ProfileRegistry& registry);
Result<LineConfig> load_line_config(const std::string& path, const ProfileRegistry& registry);

}  // namespace lb::profiles
