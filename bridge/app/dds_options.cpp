#include "app/dds_options.hpp"

#include <filesystem>

namespace lb::app {
namespace {

ddsl::SecurityFiles files_of(const profiles::DdsSecurityConfig& s) {
  return {s.identity_ca, s.certificate, s.private_key, s.permissions_ca, s.governance, s.permissions, s.properties};
}

}  // namespace

ddsl::ParticipantOptions bridge_participant_options(const profiles::LineConfig& line) {
  ddsl::ParticipantOptions o{line.dds.domain, line.dds.localhost_only, "linebridge/" + line.line, std::nullopt};
  if (line.dds.security) o.security = files_of(*line.dds.security);
  return o;
}

Result<ddsl::ParticipantOptions> client_participant_options(const profiles::LineConfig& line, std::string name,
                                                            const std::string& identity_dir) {
  ddsl::ParticipantOptions o{line.dds.domain, line.dds.localhost_only, std::move(name), std::nullopt};
  if (!line.dds.security) {
    if (!identity_dir.empty()) {
      return make_error("line " + line.line + " is not secured (no dds.security in its file): --identity " + identity_dir +
                        " has no use there");
    }
    return o;
  }
  if (identity_dir.empty()) {
    return make_error("line " + line.line +
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
