// dds.security in the line file: the six files (relative ones taken from the line file's folder),
// extra dds.sec.* properties, and the mistakes that stop start-up with file:line:column.
#include <gtest/gtest.h>

#include <string>

#include "profiles/line_config.hpp"

using lb::profiles::parse_line_config;
using lb::profiles::ProfileRegistry;

namespace {

std::string line(const std::string& security) {
  return "line: test\n"
         "dds:\n"
         "  domain: 7\n" +
         security +
         "buses:\n"
         "  - {name: ext, interface: 'virtual:x'}\n"
         "devices:\n"
         "  - {name: saw1, bus: ext, node_id: 3, profile: cia420-4, version: '3.1'}\n";
}

const std::string kFiles = "  security:\n"
                           "    identity_ca: ca/identity_ca.pem\n"
                           "    certificate: bridge/cert.pem\n"
                           "    private_key: /secret/key.pem\n"
                           "    permissions_ca: ca/permissions_ca.pem\n"
                           "    governance: ../governance.p7s\n"
                           "    permissions: bridge/permissions.p7s\n";

std::string error_of(const std::string& text) {
  const auto registry = ProfileRegistry::builtin();
  auto cfg = parse_line_config(text, "/etc/linebridge/line.yaml", registry);
  return cfg ? std::string() : cfg.error().message;
}

}  // namespace

TEST(DdsSecurityConfig, AbsentMeansUnsecured) {
  const auto registry = ProfileRegistry::builtin();
  auto cfg = parse_line_config(line(""), "/etc/linebridge/line.yaml", registry);
  ASSERT_TRUE(cfg) << cfg.error().message;
  EXPECT_FALSE(cfg->dds.security.has_value());
}

TEST(DdsSecurityConfig, RelativePathsAreTakenFromTheLineFilesFolder) {
  const auto registry = ProfileRegistry::builtin();
  auto cfg = parse_line_config(line(kFiles + "    properties: {dds.sec.auth.builtin.PKI-DH.password: s3cret}\n"),
                               "/etc/linebridge/line.yaml", registry);
  ASSERT_TRUE(cfg) << cfg.error().message;
  const auto& s = *cfg->dds.security;
  EXPECT_EQ(s.identity_ca, "/etc/linebridge/ca/identity_ca.pem");
  EXPECT_EQ(s.certificate, "/etc/linebridge/bridge/cert.pem");
  EXPECT_EQ(s.private_key, "/secret/key.pem");
  EXPECT_EQ(s.permissions_ca, "/etc/linebridge/ca/permissions_ca.pem");
  EXPECT_EQ(s.governance, "/etc/governance.p7s");
  EXPECT_EQ(s.permissions, "/etc/linebridge/bridge/permissions.p7s");
  ASSERT_EQ(s.properties.size(), 1u);
  EXPECT_EQ(s.properties[0].first, "dds.sec.auth.builtin.PKI-DH.password");
  EXPECT_EQ(s.properties[0].second, "s3cret");
}

TEST(DdsSecurityConfig, MistakesStopStartUpWithTheirPlace) {
  std::string missing = kFiles;
  missing.erase(missing.find("    governance:"), std::string("    governance: ../governance.p7s\n").size());
  EXPECT_NE(error_of(line(missing)).find("line.yaml:5:5: dds.security: missing required key 'governance'"),
            std::string::npos)
      << error_of(line(missing));
  EXPECT_NE(error_of(line(kFiles + "    permisions: x\n")).find("unknown key 'permisions' in dds.security"),
            std::string::npos);
  EXPECT_NE(
      error_of(line(kFiles + "    properties: {fastdds.push_mode: 'false'}\n")).find("is not a dds.sec.* property"),
      std::string::npos);
  EXPECT_NE(error_of(
                line(kFiles + "    properties: {dds.sec.access.builtin.Access-Permissions.permissions: file:///x}\n"))
                .find("names a file: give it with its own dds.security key"),
            std::string::npos);
  std::string uri = kFiles;
  uri.replace(uri.find("ca/identity_ca.pem"), 18, "file:///ca.pem");
  EXPECT_NE(error_of(line(uri)).find("identity_ca is a path, not a URI"), std::string::npos) << error_of(line(uri));
}
