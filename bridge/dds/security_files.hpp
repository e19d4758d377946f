#pragma once
// The files of a secured DDS participant (DDS Security: PKI-DH authentication, Access-Permissions,
// AES-GCM-GMAC), and the checks the bridge makes on them before Fast DDS sees them. Fast DDS 2.9
// refuses a bad file with "initialization error" and nothing else, and a remote mismatch (another
// CA, another governance) with silence: the two sides simply never match. So every problem is
// found here, with the file and the reason, the way Fast DDS would judge it.

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "base/result.hpp"
#include "dds/grant_audit.hpp"

namespace lb::ddsl {

struct SecurityFiles {
  // Absolute paths. The identity CA signs every participant's certificate; the permissions CA
  // signs the governance (one per domain, the same for every participant) and every permissions
  // document (one per identity).
  std::string identity_ca;
  std::string certificate;
  std::string private_key;
  std::string permissions_ca;
  std::string governance;
  std::string permissions;
  // More participant properties for Fast DDS's security plugins (e.g. a key password), applied
  // after the bridge's own; the files above cannot be replaced this way.
  std::vector<std::pair<std::string, std::string>> properties;
  // The identity CA's certificate revocation list (dds.security identity_crl); empty: none.
  std::string identity_crl = {};
  // When set, every grant of the permissions document is compared with what its role is given
  // (grant_audit.hpp): the bridge's own file at start and --check, a client's in
  // `linebridge-security check --identity`. Test participants leave it unset.
  std::optional<GrantPolicy> grant_policy = std::nullopt;
};

// Every problem found, one per line, each naming its file: unreadable files, certificates that are
// not from the identity CA or have expired, a key that does not belong to its certificate,
// documents that are not signed, signed by another CA, signed without `-text` or edited after
// signing, a permissions document without a valid grant for the certificate's subject (the
// subject in another order, the grant expired), a governance that does not protect the domain.
Result<void> check_security_files(const SecurityFiles& files, std::uint32_t domain);

// What does not stop a start but should be seen (logged, printed by the pre-flight checks): an
// identity CRL whose next update is near, CA private keys beside the identity in use.
std::vector<std::string> security_warnings(const SecurityFiles& files);

// The subject of a PEM certificate in RFC 2253 order, as Fast DDS compares it with grants.
Result<std::string> certificate_subject(const std::string& certificate_path);

}  // namespace lb::ddsl
