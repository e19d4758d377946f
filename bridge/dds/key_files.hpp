#pragma once
// Private keys on disk: the participant's own key must be readable by its owner only, and no CA
// private key may lie where a running identity is (whoever reads a CA key issues identities and
// signs permissions for the whole line; pki.sh keeps them in ca-private/, to be taken offline).

#include <optional>
#include <string>
#include <vector>

#include "dds/file_findings.hpp"

namespace lb::ddsl {

// Why the private key at `path` is refused: readable, writable or executable by group or others
// (mode & 077), with its mode; nullopt when only its owner has access (or it cannot be stat'ed:
// the reading check reports that).
std::optional<std::string> private_key_mode_problem(const std::string& path);

// Warnings (key "CA key") for private keys found in the folders of `files_in_use` (and their ca/
// subfolders): any ca/*.key, and any key whose public key is that of a certificate in
// `ca_certificates` (PEM files). `own_key` is the participant's own key, not reported.
std::vector<FileFinding> ca_keys_beside(const std::vector<std::string>& files_in_use,
                                        const std::vector<std::string>& ca_certificates, const std::string& own_key);

}  // namespace lb::ddsl
