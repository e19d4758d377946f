#pragma once
// What the integration tests read off a running line, written once: a device's state on its
// status topic, one node's or one PDO's entry in the bridge's samples, and the line-file entry of
// a saw as the master tests configure it.

#include <string>

#include "msgs/commonPubSubTypes.h"

namespace lb::test {

// Online and operational (CiA 301 05h) as the status topic says: any device type's status.
template <class Status>
bool operational(const Status& s) {
  return s.health().online() && s.health().nmt_state() == linebridge_msgs::msg::NMT_OPERATIONAL;
}

// The element of `items` whose `key(item)` is `value`, or nullptr.
template <class Items, class Key>
auto find_named(const Items& items, Key key, const std::string& value) -> decltype(&*items.begin()) {
  for (const auto& item : items) {
    if (key(item) == value) return &item;
  }
  return nullptr;
}

// One device's entry in the bridge's diagnostics, or nullptr.
inline const linebridge_msgs::msg::NodeDiagnostics* node_of(const linebridge_msgs::msg::Diagnostics& d,
                                                            const std::string& device) {
  return find_named(
      d.nodes(), [](const auto& n) { return n.device(); }, device);
}

// One PDO (tpdo1, rpdo1, ...) on a device's info, or nullptr.
inline const linebridge_msgs::msg::PdoInfo* pdo_of(const linebridge_msgs::msg::DeviceInfo& info,
                                                   const std::string& name) {
  return find_named(
      info.pdos(), [](const auto& p) { return p.name(); }, name);
}

// A saw 420-4 3.1 on bus b, supervised at 400 ms and booted again every second after a failure;
// `extra` adds keys (indented by four).
inline std::string saw_entry(const std::string& name, int node_id, const std::string& extra = "") {
  return "  - name: " + name + "\n    bus: b\n    node_id: " + std::to_string(node_id) +
         "\n    profile: cia420-4\n    version: '3.1'\n    heartbeat_timeout_ms: 400\n    boot_retry_ms: 1000\n" +
         extra;
}

}  // namespace lb::test
