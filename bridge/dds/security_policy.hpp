#pragma once
// What a secured line allows whom: the governance document of a domain and the permissions of
// each role, as DDS Security XML (to be signed with the permissions CA, launch_scripts/pki.sh).
//
// Per-device rights on the line-wide services: their requests all travel on one topic per service
// (rq/<line>/bridge/<service>Request), so a grant on the topic alone cannot say "commands of saw1
// only". In a secured line a client therefore publishes each request in the DDS partition named
// after its device, the grant lists the partitions (devices) a role may publish in, and Fast DDS
// enforces that on both sides (a local writer in another partition is not created; a remote one
// is never matched). The bridge then answers a request only when its device is among the
// partitions its writer was matched with (RequestPartitions, ServiceServer).

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lb::ddsl {

enum class Role {
  observer,   // reads status, events (cuts, emergencies, feeder events), device info, diagnostics
  operator_,  // also set values, momentary commands and feeder commands of its devices
  engineer,   // also NMT, SDO, parameters and the feeder configuration services of its devices
  bridge,     // the gateway itself: writes every rt/ and rr/ topic of its line, reads requests and set values
};
std::optional<Role> role_from_string(std::string_view name);
std::string_view to_string(Role role);

// A topic that no grant may allow: a secured participant proves that access control is in force
// by failing to create a writer on it (security_proof.hpp).
inline constexpr std::string_view kAccessProbeTopic = "linebridge/access_control_probe";

struct Grant {
  std::string line;
  std::uint32_t domain = 0;
  std::string subject;  // the certificate's subject in RFC 2253 order
  Role role = Role::observer;
  std::vector<std::string> devices;  // operator/engineer: devices they may command; empty = all
  std::string not_before;            // YYYY-MM-DDThh:mm:ss, the host's local time (as Fast DDS reads it)
  std::string not_after;
};

// Governance for one domain: no unauthenticated participants, join access control, discovery and
// liveliness encrypted, every topic with read and write access control, metadata and data ENCRYPT.
std::string governance_xml(std::uint32_t domain);
std::string permissions_xml(const Grant& grant);

}  // namespace lb::ddsl
