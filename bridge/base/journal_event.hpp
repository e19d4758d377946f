#pragma once
// The bridge's key events as log lines a maintenance team can search: a device online or lost, a
// boot that failed, an EMCY, a bus off and back, the DDS side gone and back, a takeover, set values
// refused at a start. Each kind has a fixed MESSAGE_ID (systemd's convention: 128 bits as 32 hex
// digits, made once with `systemd-id128 new`; docs/operations.md lists them with the journalctl
// line that finds each), and its line carries its fields (LB_LINE, LB_BUS, LB_DEVICE, LB_NODE and
// the kind's own) in a trailer that a reader and a program read alike:
//   vcan:can0: node 5 lost: no heartbeat for 400 ms {LB_EVENT=device_lost LB_LINE=demo LB_BUS=can0 ...}
// An event is logged through spdlog like any line, so from a bus loop it costs what any line costs
// there (the AsyncLog's queue: never a wait). The line is tagged (its spdlog source location) so the
// log's sink can tell it from the others without reading its text: under systemd that sink
// (app/journal_sink) sends it to the journal as an entry of its own with MESSAGE_ID, PRIORITY and the
// fields; elsewhere the line is written as it is. Nothing here needs libsystemd, so every layer may
// log an event (docs/architecture.md: only app/ links it).

#include <spdlog/spdlog.h>

#include <array>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lb::journal {

enum class Event : std::uint8_t {
  device_online,       // its first heartbeat, or the first after it was lost
  device_lost,         // no heartbeat within its timeout
  boot_failed,         // a boot (CiA 302-2) ended with an error: LB_BOOT_ERROR is its letter
  emcy,                // an emergency message
  bus_off,             // the bus's controller went bus-off, or its link went down
  bus_back,            // error-active again after that
  dds_side_gone,       // the bus process's DDS side left the channel
  dds_side_back,       // a DDS side connected again after one left
  takeover,            // a standby began to master its bus
  set_values_refused,  // a start did not put back set values (the start-up policy)
};

struct EventKind {
  Event event;
  std::string_view name;        // LB_EVENT
  std::string_view message_id;  // MESSAGE_ID: never changes once released (searches and alerts name it)
};

inline constexpr std::array<EventKind, 10> kEvents{{
    {Event::device_online, "device_online", "fecb2be038e74664b679c1f1ed7526f6"},
    {Event::device_lost, "device_lost", "6279545544e24482b4b2b0a619f497d2"},
    {Event::boot_failed, "boot_failed", "81ae36bb585b4005a82d8f9b62a26efa"},
    {Event::emcy, "emcy", "51e2dad1f02c4e3dbc684cece2f56c0d"},
    {Event::bus_off, "bus_off", "a60a2eecec2145e5b8616efcc9551933"},
    {Event::bus_back, "bus_back", "a1a3a975e07e4752b1bec8cd4c4fa09b"},
    {Event::dds_side_gone, "dds_side_gone", "3da26d56a43344538469b32eaa7a10fb"},
    {Event::dds_side_back, "dds_side_back", "ed00515540b8490389079f63dd96153f"},
    {Event::takeover, "takeover", "789f545cc4b94fb1a15e75e8d00f15fe"},
    {Event::set_values_refused, "set_values_refused", "4f3e3f3062044106ad0f5072e28bc48b"},
}};

const EventKind& kind(Event event);
const EventKind* kind_named(std::string_view name);

// The fields every event may carry (journal field names: capitals, digits, '_').
inline constexpr std::string_view kEventField = "LB_EVENT";
inline constexpr std::string_view kLine = "LB_LINE";
inline constexpr std::string_view kBus = "LB_BUS";
inline constexpr std::string_view kDevice = "LB_DEVICE";
inline constexpr std::string_view kNode = "LB_NODE";
// The kinds' own.
inline constexpr std::string_view kNmtState = "LB_NMT_STATE";                       // device_online: as it reported
inline constexpr std::string_view kHeartbeatTimeoutMs = "LB_HEARTBEAT_TIMEOUT_MS";  // device_lost
inline constexpr std::string_view kBootError = "LB_BOOT_ERROR";        // boot_failed: the CiA 302-2 letter (B..O)
inline constexpr std::string_view kSdoAbort = "LB_SDO_ABORT";          // boot_failed: the SDO abort code, 8 hex digits
inline constexpr std::string_view kEmcyCode = "LB_EMCY_CODE";          // emcy: 4 hex digits
inline constexpr std::string_view kEmcyRegister = "LB_EMCY_REGISTER";  // emcy: 1001h, 2 hex digits
inline constexpr std::string_view kEmcyManufacturer = "LB_EMCY_MANUFACTURER";  // emcy: 5 bytes, 10 hex digits
inline constexpr std::string_view kBusState = "LB_BUS_STATE";                  // bus_off, bus_back: bus-off, down ...
inline constexpr std::string_view kBusStateBefore = "LB_BUS_STATE_BEFORE";
inline constexpr std::string_view kDdsPid = "LB_DDS_PID";              // dds_side_gone, dds_side_back
inline constexpr std::string_view kMasterNode = "LB_MASTER_NODE";      // takeover: the master it took over from
inline constexpr std::string_view kRestoreScope = "LB_RESTORE_SCOPE";  // set_values_refused: all, non_enabling, nothing
inline constexpr std::string_view kEnablingOff = "LB_ENABLING_OFF";    // set_values_refused: levels switched off
inline constexpr std::string_view kKeptRefused =
    "LB_KEPT_REFUSED";  // set_values_refused: RPDOs whose kept values were refused

// Whom an event concerns (empty, 0: not named: a bus event has no device).
struct Where {
  std::string line;
  std::string bus;
  std::string device;
  std::uint8_t node = 0;

  static Where of_line(std::string line) { return {std::move(line), {}, {}, 0}; }
  static Where of_bus(std::string line, std::string bus) { return {std::move(line), std::move(bus), {}, 0}; }
  static Where of_device(std::string line, std::string bus, std::string device, std::uint8_t node = 0) {
    return {std::move(line), std::move(bus), std::move(device), node};
  }
};

// A field of the event's kind; one with an empty value is left out (an EMCY's manufacturer bytes
// are always there, a boot error's letter is not).
struct Field {
  std::string_view name;
  std::string value;
};

// The text of an event's line and where its trailer begins.
struct Line {
  std::string text;
  std::size_t trailer = 0;
};
Line encode(Event event, const Where& where, std::string_view message, std::initializer_list<Field> fields = {});

// Logs the event at `level` on spdlog's default logger (the AsyncLog's in the bridge).
void log(Event event, spdlog::level::level_enum level, const Where& where, std::string_view message,
         std::initializer_list<Field> fields = {});

// An event's line read back: what the log's sink sends to the journal.
struct Decoded {
  const EventKind* kind = nullptr;
  std::vector<std::pair<std::string, std::string>> fields;  // in the line's order, LB_EVENT first
};
// Null when the line is no event's (or its trailer is not one this file wrote).
std::optional<Decoded> decode(const spdlog::details::log_msg& msg);
std::optional<Decoded> decode(std::string_view text, std::size_t trailer);

}  // namespace lb::journal
