#pragma once
// The identity CRL (dds.security identity_crl), checked as Fast DDS 2.9.1 will use it: PKIDH.cpp
// adds it to the identity CA's store and verifies every certificate, its own and each remote
// participant's, with X509_V_FLAG_CRL_CHECK. So a CRL that is not the identity CA's, is not yet
// valid or has expired makes every verification fail: the participant refuses its own identity
// and no remote participant authenticates. Those are problems (no start); a next update that is
// near is a warning, so the CRL is renewed (launch_scripts/pki.sh revoke) before that happens.

#include <chrono>
#include <ctime>
#include <string>

#include "dds/file_findings.hpp"

namespace lb::ddsl {

// A next update closer than this is warned about.
inline constexpr std::chrono::hours kCrlRenewWarning{7 * 24};

// Problems and warnings about `crl_path` (key "identity_crl") for a participant whose identity CA
// file is `identity_ca_path` and whose certificate is `certificate_path` (revoked: a problem, as
// Fast DDS refuses it), judged at `now`.
FileFindings check_identity_crl(const std::string& crl_path, const std::string& identity_ca_path,
                                const std::string& certificate_path, std::time_t now);

}  // namespace lb::ddsl
