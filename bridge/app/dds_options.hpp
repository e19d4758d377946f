#pragma once
// The DDS participant options of a line's processes: the bridge takes its identity from the line
// file (dds.security); a client (linebridge-cli, a tool) takes its own identity from a folder as
// launch_scripts/pki.sh issues them (cert.pem, key.pem, permissions.p7s) and the line's CAs and
// governance from the line file.

#include <string>

#include "base/result.hpp"
#include "dds/participant.hpp"
#include "profiles/line_config.hpp"

namespace lb::app {

ddsl::ParticipantOptions bridge_participant_options(const profiles::LineConfig& line);

// What the grants of the line's permissions documents are judged against (grant_audit.hpp): the
// line, its devices and the bridge's identity (its certificate's subject; empty if unreadable).
ddsl::GrantPolicy grant_policy(const profiles::LineConfig& line);

// identity_dir empty: only for an unsecured line. A secured line without an identity, or an
// identity for an unsecured line, is a configuration error.
Result<ddsl::ParticipantOptions> client_participant_options(const profiles::LineConfig& line, std::string name,
                                                            const std::string& identity_dir);

// "DDS security: identity 'CN=...', governance ..." for start-up logs; "" when unsecured.
std::string security_summary(const ddsl::ParticipantOptions& options);

}  // namespace lb::app
