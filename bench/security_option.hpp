#pragma once
// --pki DIR --identity NAME: a bench participant secured with an identity launch_scripts/pki.sh
// issued (DIR/ca/*.pem, DIR/governance.p7s, DIR/NAME/{cert.pem,key.pem,permissions.p7s}), so that
// bench.sh can measure a figure secured and unsecured side by side. Without --pki: unsecured.

#include <CLI/CLI.hpp>

#include <string>

#include "dds/participant.hpp"

namespace lb::bench {

struct SecurityOption {
  std::string pki;
  std::string identity;

  void add(CLI::App& cli) {
    auto* p = cli.add_option("--pki", pki,
                             "DDS Security: the PKI folder launch_scripts/pki.sh made (default: unsecured)");
    cli.add_option("--identity", identity, "DDS Security: the identity's folder in the PKI")->needs(p);
  }

  lb::ddsl::ParticipantOptions options(int domain, std::string name) const {
    lb::ddsl::ParticipantOptions o{static_cast<std::uint32_t>(domain), true, std::move(name), std::nullopt};
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
};

}  // namespace lb::bench
