#pragma once
// Fail-closed: a participant created with security properties may still run without security.
// Fast DDS 2.9 silently skips any plugin whose property it does not know (a misspelled
// dds.sec.auth.plugin gives a participant with no security at all, and logs nothing), and a
// library built without security ignores them all. So a secured participant proves, right after
// it is created, that authentication, access control and encryption are really in force.

#include <fastdds/dds/domain/DomainParticipant.hpp>

#include "base/result.hpp"

namespace lb::ddsl {

// Ok, or what is not in force and the property behind it. Checks:
// - authentication: the GUID prefix was derived from the identity certificate (PKI-DH sets the
//   top bit of its first byte; Fast DDS's own prefixes start with 01.0f);
// - access control: a writer on kAccessProbeTopic, which no grant may allow, cannot be created;
// - encryption: the cryptography plugin property names Fast DDS's only built-in one
//   (builtin.AES-GCM-GMAC). Fast DDS 2.9 offers no way to observe the plugin from the outside;
//   with authentication proven the library has security, and it creates exactly this plugin for
//   exactly this value (SecurityPluginFactory).
Result<void> prove_security_active(eprosima::fastdds::dds::DomainParticipant& participant);

}  // namespace lb::ddsl
