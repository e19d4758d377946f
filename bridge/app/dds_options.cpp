#include "app/dds_options.hpp"

#include <filesystem>

namespace lb::app {
namespace {

ddsl::SecurityFiles files_of(const profiles::DdsSecurityConfig& s) {
  ddsl::SecurityFiles files{s.identity_ca, s.certificate, s.private_key, s.permissions_ca,
                            s.governance,  s.permissions, s.properties};
  files.identity_crl = s.identity_crl;
  return files;
}

// The line file's site settings, the same for the bridge and every client of the line.
ddsl::ParticipantOptions line_options(const profiles::LineConfig& line, std::string name) {
  ddsl::ParticipantOptions o;
  o.domain = line.dds.domain;
  o.localhost_only = line.dds.localhost_only;
  o.name = std::move(name);
  o.profiles_file = line.dds.profiles_file;
  o.participant_profile = line.dds.participant_profile;
  o.shared_memory = line.dds.shared_memory;
  o.gate.pending = line.dds.max_pending_participants;
  for (const auto& s : line.dds.discovery_servers) o.discovery_servers.push_back({s.id, s.address, s.port});
  return o;
}

}  // namespace

ddsl::ParticipantOptions bridge_participant_options(const profiles::LineConfig& line) {
  auto o = line_options(line, "linebridge/" + line.line);
  if (line.dds.security) {
    o.security = files_of(*line.dds.security);
    o.security->grant_policy = grant_policy(line);
  }
  return o;
}

ddsl::GrantPolicy grant_policy(const profiles::LineConfig& line) {
  ddsl::GrantPolicy policy;
  policy.line = line.line;
  for (const auto& d : line.devices) policy.devices.push_back(d.name);
  if (line.dds.security) {
    if (auto subject = ddsl::certificate_subject(line.dds.security->certificate)) policy.bridge_subject = *subject;
  }
  return policy;
}

Result<ddsl::ParticipantOptions> client_participant_options(const profiles::LineConfig& line, std::string name,
                                                            const std::string& identity_dir) {
  auto o = line_options(line, std::move(name));
  if (!line.dds.security) {
    if (!identity_dir.empty()) {
      return make_error("line " + line.line + " is not secured (no dds.security in its file): --identity " +
                        identity_dir + " has no use there");
    }
    return o;
  }
  if (identity_dir.empty()) {
    return make_error(
        "line " + line.line +
        " is secured (dds.security): give this client an identity with --identity DIR or LINEBRIDGE_IDENTITY "
        "(a folder with cert.pem, key.pem and permissions.p7s, as launch_scripts/pki.sh issue makes it)");
  }
  const auto dir = std::filesystem::absolute(identity_dir);
  ddsl::SecurityFiles f = files_of(*line.dds.security);
  f.certificate = (dir / "cert.pem").string();
  f.private_key = (dir / "key.pem").string();
  f.permissions = (dir / "permissions.p7s").string();
  o.security = std::move(f);
  return o;
}

std::string security_summary(const ddsl::ParticipantOptions& options) {
  if (!options.security) return "";
  auto subject = ddsl::certificate_subject(options.security->certificate);
  return "DDS security in force (authentication, access control, encryption): identity '" +
         (subject ? *subject : std::string("?")) + "', permissions " + options.security->permissions + ", governance " +
         options.security->governance;
}

}  // namespace lb::app
