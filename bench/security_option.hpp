#pragma once
// --pki DIR --identity NAME: a bench participant secured with an identity launch_scripts/pki.sh
// issued (DIR/ca/*.pem, DIR/governance.p7s, DIR/NAME/{cert.pem,key.pem,permissions.p7s}), so that
// bench.sh can measure a figure secured and unsecured side by side. Without --pki: unsecured.

#include <CLI/CLI.hpp>

#include <string>

#include "dds/participant.hpp"
#include "program.hpp"

namespace lb::bench {

// The options of a participant named name in domain, secured with pki/identity when pki is set.
inline lb::ddsl::ParticipantOptions participant_options(int domain, std::string name, const std::string& pki,
                                                        const std::string& identity) {
  lb::ddsl::ParticipantOptions o{static_cast<std::uint32_t>(domain), true, std::move(name), std::nullopt};
  o.shared_memory = shared_memory_transport();
  if (!pki.empty()) {
    const std::string id = pki + "/" + identity;
    o.security = lb::ddsl::SecurityFiles{pki + "/ca/identity_ca.pem",
                                         id + "/cert.pem",
                                         id + "/key.pem",
                                         pki + "/ca/permissions_ca.pem",
                                         pki + "/governance.p7s",
                                         id + "/permissions.p7s",
                                         {}};
  }
  return o;
}

// A Program's participant: its --domain, --pki and --identity (Program::add_security).
inline lb::ddsl::ParticipantOptions participant_options(const Program& program, std::string name) {
  return participant_options(program.domain, std::move(name), program.pki, program.identity);
}

// For a program that is not a bench::Program (its own command line).
struct SecurityOption {
  std::string pki;
  std::string identity;

  void add(CLI::App& cli) { add_security_options(cli, pki, identity); }

  lb::ddsl::ParticipantOptions options(int domain, std::string name) const {
    return participant_options(domain, std::move(name), pki, identity);
  }
};

}  // namespace lb::bench
