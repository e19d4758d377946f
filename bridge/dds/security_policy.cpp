#include "dds/security_policy.hpp"

#include <array>

#include "dds/participant.hpp"  // request_topic, reply_topic
#include "dds/topic_names.hpp"

namespace lb::ddsl {
namespace {

// What the bridge publishes per device and what reaches which role. Topic expressions are
// fnmatch patterns (Fast DDS), so "*" also stands for a device not configured yet.
constexpr std::array kObservedTopics{"status", "cut", "emergency", "info", "unwinding", "feeder_error"};
constexpr std::array kSetValueTopics{"setpoint", "loom"};  // apps -> bridge, per device
constexpr std::array kSetValueResults{"setpoint_result", "loom_result"};
constexpr std::array kOperatorLineServices{"command"};  // line-wide, partitioned by device
constexpr std::array kEngineerLineServices{"nmt", "sdo_read", "sdo_write", "get_parameter", "set_parameter"};
constexpr std::array kOperatorDeviceServices{"feeder_command"};  // a feeder box's own services
constexpr std::array kEngineerDeviceServices{"feeder_test", "feeder_functions", "feeder_assignment",
                                             "weft_insertion_type", "trigger_source"};

std::string escaped(std::string_view s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

class Rule {
 public:
  void publish(std::string topic) { publish_.push_back(std::move(topic)); }
  void subscribe(std::string topic) { subscribe_.push_back(std::move(topic)); }
  void partitions(std::vector<std::string> p) { partitions_ = std::move(p); }
  bool empty() const { return publish_.empty() && subscribe_.empty(); }

  std::string xml(std::uint32_t domain) const {
    std::string x = "      <allow_rule>\n        <domains><id>" + std::to_string(domain) + "</id></domains>\n";
    x += block("publish", publish_);
    x += block("subscribe", subscribe_);
    return x + "      </allow_rule>\n";
  }

 private:
  std::string block(const char* kind, const std::vector<std::string>& topics) const {
    if (topics.empty()) return {};
    std::string x = std::string("        <") + kind + ">\n          <topics>\n";
    for (const auto& t : topics) x += "            <topic>" + escaped(t) + "</topic>\n";
    x += "          </topics>\n";
    if (!partitions_.empty()) {
      x += "          <partitions>\n";
      for (const auto& p : partitions_) x += "            <partition>" + escaped(p) + "</partition>\n";
      x += "          </partitions>\n";
    }
    return x + std::string("        </") + kind + ">\n";
  }

  std::vector<std::string> publish_;
  std::vector<std::string> subscribe_;
  std::vector<std::string> partitions_;  // empty: the default partition only
};

template <class Names>
void add_services(Rule& requests, Rule& replies, const std::string& path_prefix, const Names& names) {
  for (const char* s : names) {
    requests.publish(request_topic(path_prefix + s));
    replies.subscribe(reply_topic(path_prefix + s));
  }
}

}  // namespace

std::optional<Role> role_from_string(std::string_view name) {
  if (name == "observer") return Role::observer;
  if (name == "operator") return Role::operator_;
  if (name == "engineer") return Role::engineer;
  if (name == "bridge") return Role::bridge;
  return std::nullopt;
}

std::string_view to_string(Role role) {
  switch (role) {
    case Role::observer: return "observer";
    case Role::operator_: return "operator";
    case Role::engineer: return "engineer";
    case Role::bridge: return "bridge";
  }
  return "?";
}

std::string governance_xml(std::uint32_t domain) {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<!-- linebridge governance of DDS domain " +
         std::to_string(domain) +
         " (launch_scripts/pki.sh). Every participant of the\n"
         "     domain must use this same document, signed by the permissions CA. -->\n"
         "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\">\n"
         "  <domain_access_rules>\n"
         "    <domain_rule>\n"
         "      <domains><id>" +
         std::to_string(domain) +
         "</id></domains>\n"
         "      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>\n"
         "      <enable_join_access_control>true</enable_join_access_control>\n"
         "      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>\n"
         "      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>\n"
         "      <rtps_protection_kind>NONE</rtps_protection_kind>\n"
         "      <topic_access_rules>\n"
         "        <topic_rule>\n"
         "          <topic_expression>*</topic_expression>\n"
         "          <enable_discovery_protection>true</enable_discovery_protection>\n"
         "          <enable_liveliness_protection>true</enable_liveliness_protection>\n"
         "          <enable_read_access_control>true</enable_read_access_control>\n"
         "          <enable_write_access_control>true</enable_write_access_control>\n"
         "          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>\n"
         "          <data_protection_kind>ENCRYPT</data_protection_kind>\n"
         "        </topic_rule>\n"
         "      </topic_access_rules>\n"
         "    </domain_rule>\n"
         "  </domain_access_rules>\n"
         "</dds>\n";
}

std::string permissions_xml(const Grant& g) {
  const std::string& line = g.line;
  const std::string bridge_prefix = line + "/" + std::string(kBridgeNamespace) + "/";
  // Fast DDS takes the first rule whose topics match and checks the writer's partitions against
  // that rule's partitions only: the partitioned line-wide requests get a rule of their own, first.
  std::vector<Rule> rules;
  if (g.role == Role::bridge) {
    Rule requests;  // the bridge reads line-wide requests in every device's partition ("*")
    requests.subscribe(request_topic(bridge_prefix + "*"));
    requests.partitions({"*"});
    Rule rest;
    rest.publish("rt/" + line + "/*");
    rest.publish("rr/" + line + "/*");
    for (const char* t : kSetValueTopics) rest.subscribe(topic_name(line, "*", t));
    rest.subscribe("rq/" + line + "/*Request");  // a feeder box's own services
    rules.push_back(std::move(requests));
    rules.push_back(std::move(rest));
  } else {
    const std::vector<std::string> devices = g.devices.empty() ? std::vector<std::string>{"*"} : g.devices;
    Rule requests;  // line-wide services, in the partitions of the role's devices
    requests.partitions(devices);
    Rule rest;
    for (const char* t : kObservedTopics) rest.subscribe(topic_name(line, "*", t));
    rest.subscribe(topic_name(line, kBridgeNamespace, "diagnostics"));
    if (g.role != Role::observer) {
      add_services(requests, rest, bridge_prefix, kOperatorLineServices);
      for (const auto& d : devices) {
        for (const char* t : kSetValueTopics) rest.publish(topic_name(line, d, t));
        for (const char* t : kSetValueResults) rest.subscribe(topic_name(line, d, t));
        add_services(rest, rest, line + "/" + d + "/", kOperatorDeviceServices);
      }
    }
    if (g.role == Role::engineer) {
      add_services(requests, rest, bridge_prefix, kEngineerLineServices);
      for (const auto& d : devices) add_services(rest, rest, line + "/" + d + "/", kEngineerDeviceServices);
    }
    if (!requests.empty()) rules.push_back(std::move(requests));
    rules.push_back(std::move(rest));
  }

  std::string x = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
                  "<!-- linebridge permissions: role " +
                  std::string(to_string(g.role)) + " on line " + line +
                  " (launch_scripts/pki.sh) -->\n"
                  "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\">\n"
                  "  <permissions>\n"
                  "    <grant name=\"" +
                  escaped(line + "_" + std::string(to_string(g.role))) +
                  "\">\n"
                  "      <subject_name>" +
                  escaped(g.subject) +
                  "</subject_name>\n"
                  "      <validity>\n"
                  "        <not_before>" +
                  escaped(g.not_before) +
                  "</not_before>\n"
                  "        <not_after>" +
                  escaped(g.not_after) +
                  "</not_after>\n"
                  "      </validity>\n";
  for (const auto& r : rules) x += r.xml(g.domain);
  x += "      <default>DENY</default>\n"
       "    </grant>\n"
       "  </permissions>\n"
       "</dds>\n";
  return x;
}

}  // namespace lb::ddsl
