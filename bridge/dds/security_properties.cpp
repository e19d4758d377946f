#include "dds/security_properties.hpp"

#include <algorithm>
#include <array>
#include <string_view>

namespace lb::ddsl {
namespace {

struct Plugin {
  std::string_view key;
  std::string_view builtin;
};
constexpr std::array kPlugins{Plugin{"dds.sec.auth.plugin", "builtin.PKI-DH"},
                              Plugin{"dds.sec.access.plugin", "builtin.Access-Permissions"},
                              Plugin{"dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC"},
                              Plugin{"dds.sec.log.plugin", "builtin.DDS_LogTopic"}};

constexpr std::array<std::string_view, 15> kSettings{
    "dds.sec.auth.builtin.PKI-DH.identity_ca",
    "dds.sec.auth.builtin.PKI-DH.identity_certificate",
    "dds.sec.auth.builtin.PKI-DH.private_key",
    "dds.sec.auth.builtin.PKI-DH.password",
    "dds.sec.auth.builtin.PKI-DH.identity_crl",
    "dds.sec.access.builtin.Access-Permissions.permissions_ca",
    "dds.sec.access.builtin.Access-Permissions.governance",
    "dds.sec.access.builtin.Access-Permissions.permissions",
    "dds.sec.crypto.keysize",
    "dds.sec.crypto.maxblockspersession",
    "dds.sec.log.builtin.DDS_LogTopic.logging_level",
    "dds.sec.log.builtin.DDS_LogTopic.log_file",
    "dds.sec.log.builtin.DDS_LogTopic.distribute",
    // Fast DDS's own bookkeeping on endpoints; harmless to name, never useful.
    "dds.sec.builtin_endpoint_name",
    "dds.sec.participant_crypto_tokens",
};

// The known key closest to a misspelled one, by shared prefix: enough to point at "identity_crl"
// for "identity_crls" or at the plugin key for "dds.sec.auth.plugins".
std::string_view closest(std::string_view key) {
  std::string_view best;
  std::size_t best_len = 0;
  const auto consider = [&](std::string_view known) {
    const auto mismatch = std::mismatch(key.begin(), key.end(), known.begin(), known.end());
    const auto len = static_cast<std::size_t>(mismatch.first - key.begin());
    if (len > best_len) best_len = len, best = known;
  };
  for (const auto& p : kPlugins) consider(p.key);
  for (const auto k : kSettings) consider(k);
  return best_len > std::string_view("dds.sec.").size() ? best : std::string_view();
}

}  // namespace

std::vector<std::pair<std::string, std::string>> security_property_problems(
    const std::vector<std::pair<std::string, std::string>>& properties) {
  std::vector<std::pair<std::string, std::string>> problems;
  for (const auto& property : properties) {
    // Named, not a structured binding: clang 14 cannot capture one in the lambda below.
    const std::string& key = property.first;
    const std::string& value = property.second;
    const auto plugin = std::find_if(kPlugins.begin(), kPlugins.end(), [&](const Plugin& p) { return p.key == key; });
    if (plugin != kPlugins.end()) {
      if (value != plugin->builtin) {
        problems.emplace_back(key, "'" + value + "' is not a plugin Fast DDS 2.9.1 has (its only one is '" +
                                       std::string(plugin->builtin) +
                                       "'); the participant would not start, or start without that protection");
      }
      continue;
    }
    if (std::find(kSettings.begin(), kSettings.end(), key) != kSettings.end()) continue;
    if (key.rfind("dds.sec.", 0) != 0) continue;  // the line file refuses those already
    const auto near = closest(key);
    problems.emplace_back(key, "not a property Fast DDS 2.9.1 reads: it would be ignored without a word" +
                                   (near.empty() ? std::string() : " (did you mean " + std::string(near) + "?)"));
  }
  return problems;
}

}  // namespace lb::ddsl
