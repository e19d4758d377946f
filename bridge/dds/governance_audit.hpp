#pragma once
// What a governance must protect besides the payloads (security_files.cpp checks those): the
// line's promise is "encryption in force", and with discovery, liveliness or metadata protection
// NONE the device, topic and type names, the grants' partitions and every participant's liveliness
// go out in clear while the bridge reports encryption. Required, for the domain rule of the
// line's domain and for each of its topic rules (what launch_scripts/pki.sh generates):
//   discovery_protection_kind  ENCRYPT  (endpoint announcements: topic, type and partition names)
//   liveliness_protection_kind ENCRYPT  (a forged liveliness message keeps a dead writer "alive")
//   enable_discovery_protection, enable_liveliness_protection: true (otherwise the topic's
//       endpoints are announced on the unprotected built-in endpoints, whatever the kinds say)
//   metadata_protection_kind   ENCRYPT  (submessages: without it a reader cannot tell a forged
//       heartbeat or gap from the writer's, and sequence numbers and writer GUIDs are readable)
// SIGN (and SIGN_WITH_ORIGIN_AUTHENTICATION) is refused too: it authenticates but leaves the
// names readable, and the promise is encryption. The *_WITH_ORIGIN_AUTHENTICATION forms of
// ENCRYPT are taken. rtps_protection_kind is not required: pki.sh leaves it NONE, because with
// discovery, liveliness, metadata and data encrypted it would only encrypt the same bytes twice.

#include <cstdint>
#include <string>
#include <vector>

namespace lb::ddsl {

// The problems of the governance document `xml` (its signed content) for `domain`, one reason per
// entry. Empty when the document does not parse or no domain rule covers the domain: the
// governance check reports those already.
std::vector<std::string> governance_protection_problems(const std::string& xml, std::uint32_t domain);

}  // namespace lb::ddsl
