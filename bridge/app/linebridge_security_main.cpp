// linebridge-security: what launch_scripts/pki.sh needs from a line file (the governance and each
// role's permissions, before openssl signs them), and the bridge's own checks of a line's security
// files, for an integrator to run before starting anything.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <ctime>
#include <sstream>

#include "app/arguments.hpp"
#include "app/dds_options.hpp"
#include "app/line_config_source.hpp"
#include "dds/security_files.hpp"
#include "dds/security_policy.hpp"

namespace {

std::string local_time_text(std::time_t t) {
  std::tm tm{};
  localtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  return buf;
}

std::vector<std::string> split(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"linebridge-security: governance and permissions of a line, and checks of its security files"};
  lb::app::add_conventions(cli, "linebridge-security", lb::app::kSecurityExitCodes);
  cli.require_subcommand(1);
  std::string config_path;
  lb::app::add_config_option(cli, config_path);

  auto* gov_cmd = cli.add_subcommand("governance", "print the governance document (XML) of the line's DDS domain");

  std::string role_name, subject, certificate, devices;
  int days = 365;
  auto* perm_cmd = cli.add_subcommand("permissions", "print the permissions document (XML) of one identity");
  perm_cmd->add_option("--role", role_name, "observer, operator, engineer or bridge")
      ->required()
      ->check(CLI::IsMember({"observer", "operator", "engineer", "bridge"}));
  auto* subject_opt = perm_cmd->add_option("--subject", subject,
                                           "the identity's subject in RFC 2253 order, e.g. CN=hmi1,O=Plant");
  perm_cmd->add_option("--certificate", certificate, "take the subject from this certificate (PEM)")
      ->excludes(subject_opt);
  perm_cmd->add_option("--devices", devices,
                       "operator/engineer: the devices it may command, comma-separated (required for an operator; an "
                       "engineer without it may command every device)");
  perm_cmd->add_option("--days", days, "the grant is valid from a day ago for this many days")
      ->check(CLI::Range(1, 36500))
      ->capture_default_str();

  std::string identity_dir;
  auto* check_cmd = cli.add_subcommand(
      "check", "check the line's security files as the bridge does before it starts (or a client's, with --identity)");
  check_cmd->add_option("--identity", identity_dir, "a client's identity folder (cert.pem, key.pem, permissions.p7s)");
  if (const int code = lb::app::parse(cli, argc, argv); code >= 0) return code;

  const auto registry = lb::profiles::ProfileRegistry::builtin();
  auto config = lb::app::load_config(config_path, registry);
  if (!config) return fmt::print(stderr, "{}\n", config.error().message), 2;

  if (gov_cmd->parsed()) {
    fmt::print("{}", lb::ddsl::governance_xml(config->dds.domain));
    return 0;
  }
  if (perm_cmd->parsed()) {
    lb::ddsl::Grant grant;
    grant.line = config->line;
    grant.domain = config->dds.domain;
    grant.role = *lb::ddsl::role_from_string(role_name);
    if (!certificate.empty()) {
      auto s = lb::ddsl::certificate_subject(certificate);
      if (!s) return fmt::print(stderr, "{}\n", s.error().message), 2;
      grant.subject = *s;
    } else {
      grant.subject = subject;
    }
    if (grant.subject.empty()) return fmt::print(stderr, "permissions: give --subject or --certificate\n"), 2;
    grant.devices = split(devices);
    const bool commands = grant.role == lb::ddsl::Role::operator_ || grant.role == lb::ddsl::Role::engineer;
    if (!commands && !grant.devices.empty()) {
      return fmt::print(stderr, "permissions: --devices is for an operator or an engineer, not a {}\n", role_name), 2;
    }
    if (grant.role == lb::ddsl::Role::operator_ && grant.devices.empty()) {
      return fmt::print(stderr, "permissions: an operator needs --devices (the devices it may set and command)\n"), 2;
    }
    for (const auto& d : grant.devices) {
      if (config->device(d) == nullptr) {
        std::string known;
        for (const auto& dev : config->devices) known += (known.empty() ? "" : ", ") + dev.name;
        return fmt::print(stderr, "permissions: no device '{}' on line {} (devices: {})\n", d, config->line, known), 2;
      }
    }
    const std::time_t now = std::time(nullptr);
    grant.not_before = local_time_text(now - 24 * 3600);  // a host whose clock is a little behind still accepts it
    grant.not_after = local_time_text(now + static_cast<std::time_t>(days) * 24 * 3600);
    fmt::print("{}", lb::ddsl::permissions_xml(grant));
    return 0;
  }
  // check
  auto options = identity_dir.empty()
                     ? lb::Result<lb::ddsl::ParticipantOptions>(lb::app::bridge_participant_options(*config))
                     : lb::app::client_participant_options(*config, "check", identity_dir);
  if (!options) return fmt::print(stderr, "{}\n", options.error().message), 2;
  if (!options->security) return fmt::print(stderr, "line {} is not secured (no dds.security)\n", config->line), 2;
  options->security->grant_policy = lb::app::grant_policy(*config);  // a client's grants too, not only the bridge's
  if (auto ok = lb::ddsl::check_security_files(*options->security, config->dds.domain); !ok) {
    return fmt::print(stderr, "{}\n", ok.error().message), 2;
  }
  for (const auto& w : lb::ddsl::grant_warnings(*options->security, config->dds.domain)) fmt::print("warning: {}\n", w);
  for (const auto& w : lb::ddsl::security_warnings(*options->security)) fmt::print("warning: {}\n", w);
  auto s = lb::ddsl::certificate_subject(options->security->certificate);
  fmt::print("ok: {} on domain {}: identity '{}' ({}), permissions {}, governance {}\n", config->line,
             config->dds.domain, s ? *s : "?", options->security->certificate, options->security->permissions,
             options->security->governance);
  return 0;
}
