#pragma once
// The dds.sec.* properties a line adds (dds.security.properties), checked before start against
// what Fast DDS 2.9.1 reads. Fast DDS looks its security properties up by exact name and ignores
// every other one without a word, and it takes a plugin by its built-in name only: a misspelled
// plugin name passed --check and stopped the bridge at start (security_proof.cpp), and a misspelled
// key (a CRL, a password) is simply not applied, which for a CRL means revocation silently not in
// force. So both are refused here, with the key, the value and what is accepted:
//   dds.sec.auth.plugin    builtin.PKI-DH               dds.sec.access.plugin builtin.Access-Permissions
//   dds.sec.crypto.plugin  builtin.AES-GCM-GMAC         dds.sec.log.plugin    builtin.DDS_LogTopic
//   dds.sec.auth.builtin.PKI-DH.{identity_ca,identity_certificate,private_key,password,identity_crl}
//   dds.sec.access.builtin.Access-Permissions.{permissions_ca,governance,permissions}
//   dds.sec.crypto.{keysize,maxblockspersession}
//   dds.sec.log.builtin.DDS_LogTopic.{logging_level,log_file,distribute}
// (the names in libfastrtps 2.9.1's security plugins: PKIDH.cpp, AccessPermissions.cpp,
// AESGCMGMAC_KeyFactory.cpp, LogTopic.cpp, SecurityManager.cpp).

#include <string>
#include <utility>
#include <vector>

namespace lb::ddsl {

// The refused properties: (key, reason), one per property.
std::vector<std::pair<std::string, std::string>> security_property_problems(
    const std::vector<std::pair<std::string, std::string>>& properties);

}  // namespace lb::ddsl
