// The pre-flight audit of a secured line (issue 25): what `linebridge --check`,
// `linebridge-security check [--identity DIR]` and the bridge's start refuse besides broken files.
// Real files: a PKI made here by launch_scripts/pki.sh, documents edited by hand and signed with
// `pki.sh sign` as an integrator would; the real linebridge-security binary for the CLI; real
// Fast DDS participants for what a participant announces (run in a netns by CTest).
#include <gtest/gtest.h>
#include <unistd.h>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "app/line_check.hpp"
#include "dds/grant_audit.hpp"
#include "dds/participant.hpp"
#include "dds/security_files.hpp"
#include "msgs/sawPubSubTypes.h"
#include "support/test_pki.hpp"
#include "support/unit_secured_line.hpp"

namespace fdds = eprosima::fastdds::dds;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint32_t kDomain = 23;

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  if (at == std::string::npos) throw std::runtime_error("'" + from + "' not in the document");
  return s.replace(at, from.size(), to);
}

// A rule inserted before the grant's <default>, as an integrator edits a grant by hand.
std::string with_rule(const std::string& xml, const std::string& rule_body) {
  return replaced(xml, "      <default>DENY</default>",
                  "      <allow_rule>\n        <domains><id>" + std::to_string(kDomain) + "</id></domains>\n" +
                      rule_body + "      </allow_rule>\n      <default>DENY</default>");
}

std::string publish(const std::string& topic, const std::string& partition = "") {
  return "        <publish><topics><topic>" + topic + "</topic></topics>" +
         (partition.empty() ? "" : "<partitions><partition>" + partition + "</partition></partitions>") +
         "</publish>\n";
}

class SecurityAudit : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = lb::test::fresh_test_dir("security_audit");
    pki_ = lb::test::pki_for(dir_, line_yaml(""));
    config_ = dir_ + "/line.yaml";
    std::ofstream(config_) << line_yaml(pki_->security_yaml());
  }

  std::string line_yaml(const std::string& security) const {
    return lb::test::secured_line_yaml(
        "sec", kDomain, security,
        "buses:\n"
        "  - {name: ext, interface: 'virtual:audit', role: master, sync_period_ms: 20}\n"
        "devices:\n"
        "  - {name: saw1, bus: ext, node_id: 5, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 400}\n"
        "  - {name: saw2, bus: ext, node_id: 6, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 400}\n");
  }

  lb::ddsl::GrantPolicy policy() const {
    return {"sec", {"saw1", "saw2"}, *lb::ddsl::certificate_subject(pki_->dir() + "/bridge/cert.pem")};
  }
  lb::ddsl::SecurityFiles files(const std::string& identity) const {
    auto f = pki_->files(identity);
    f.grant_policy = policy();
    return f;
  }
  // The identity's permissions.xml edited and signed again with pki.sh sign (permissions.p7s).
  void resign(const std::string& identity, const std::string& xml) const {
    std::ofstream(identity + "/permissions.xml") << xml;
    pki_->sign(identity + "/permissions.xml");
  }
  std::string errors_of(const lb::ddsl::SecurityFiles& f) const {
    auto r = lb::ddsl::check_security_files(f, kDomain);
    return r ? std::string() : r.error().message;
  }

  struct Run {
    int exit_code;
    std::string output;
  };
  // The real linebridge-security binary.
  Run security_check(const std::string& identity) const {
    const std::string log = dir_ + "/check_" + std::to_string(++runs_) + ".log";
    const int code = lb::test::shell("'" LB_BIN_SECURITY "' --config '" + config_ + "' check" +
                                         (identity.empty() ? "" : " --identity '" + identity + "'"),
                                     log);
    return {code, lb::test::read_text(log)};
  }
  // linebridge --check, the function the binary runs.
  Run line_check() const {
    char* out_buf = nullptr;
    std::size_t out_len = 0;
    std::FILE* out = ::open_memstream(&out_buf, &out_len);
    const auto registry = lb::profiles::ProfileRegistry::builtin();
    const int code = lb::app::check_line(config_, registry, out, out);
    std::fclose(out);
    std::string text(out_buf, out_len);
    std::free(out_buf);  // NOLINT: open_memstream's buffer is malloc'ed
    return {code, text};
  }

  std::string dir_, config_;
  std::unique_ptr<lb::test::TestPki> pki_;
  mutable int runs_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Governance.

TEST_F(SecurityAudit, GovernanceThatPkiShGeneratesPasses) {
  EXPECT_EQ(errors_of(files(pki_->dir() + "/bridge")), "");
  const auto r = security_check("");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST_F(SecurityAudit, GovernanceWithoutDiscoveryLivelinessOrMetadataEncryptionIsRefused) {
  const std::string original = lb::test::read_text(pki_->dir() + "/governance.xml");
  ASSERT_NE(original.find("<dds"), std::string::npos);
  struct Variant {
    std::string from, to, expected;
  };
  const std::vector<Variant> variants{
      {"<discovery_protection_kind>ENCRYPT", "<discovery_protection_kind>NONE", "discovery_protection_kind NONE"},
      {"<liveliness_protection_kind>ENCRYPT", "<liveliness_protection_kind>NONE", "liveliness_protection_kind NONE"},
      {"<metadata_protection_kind>ENCRYPT", "<metadata_protection_kind>NONE", "metadata_protection_kind NONE"},
      {"<metadata_protection_kind>ENCRYPT", "<metadata_protection_kind>SIGN", "metadata_protection_kind SIGN"},
      {"<enable_discovery_protection>true", "<enable_discovery_protection>false",
       "enable_discovery_protection is not true"},
      {"<enable_liveliness_protection>true", "<enable_liveliness_protection>false",
       "enable_liveliness_protection is not true"},
  };
  int n = 0;
  for (const auto& v : variants) {
    const std::string xml = dir_ + "/gov" + std::to_string(++n) + ".xml";
    std::ofstream(xml) << replaced(original, v.from, v.to);
    pki_->sign(xml);
    auto f = files(pki_->dir() + "/bridge");
    f.governance = dir_ + "/gov" + std::to_string(n) + ".p7s";
    const std::string errors = errors_of(f);
    EXPECT_NE(errors.find(v.expected), std::string::npos) << v.to << " was not refused: '" << errors << "'";
    EXPECT_NE(errors.find(f.governance), std::string::npos) << errors;
  }
  // All three NONE, as the issue found it: linebridge --check refuses to call the line ok.
  std::string all = replaced(original, "<discovery_protection_kind>ENCRYPT", "<discovery_protection_kind>NONE");
  all = replaced(all, "<liveliness_protection_kind>ENCRYPT", "<liveliness_protection_kind>NONE");
  all = replaced(all, "<metadata_protection_kind>ENCRYPT", "<metadata_protection_kind>NONE");
  std::ofstream(pki_->dir() + "/governance.xml") << all;
  pki_->sign(pki_->dir() + "/governance.xml");
  const auto check = line_check();
  EXPECT_NE(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("discovery_protection_kind NONE"), std::string::npos) << check.output;
  const auto cli = security_check("");
  EXPECT_EQ(cli.exit_code, 2) << cli.output;
  EXPECT_NE(cli.output.find("metadata_protection_kind NONE"), std::string::npos) << cli.output;
}

// ---------------------------------------------------------------------------------------------
// Grants.

TEST_F(SecurityAudit, GrantsThatPkiShIssuesPass) {
  for (const auto& [name, role, devices] :
       std::vector<std::tuple<std::string, std::string, std::string>>{{"obs", "observer", ""},
                                                                      {"op", "operator", "saw1"},
                                                                      {"eng", "engineer", ""},
                                                                      {"eng1", "engineer", "saw2"}}) {
    const auto id = pki_->issue(name, role, devices);
    EXPECT_EQ(errors_of(files(id)), "") << name;
    EXPECT_TRUE(lb::ddsl::grant_warnings(files(id), kDomain).empty()) << name;
    const auto r = security_check(id);
    EXPECT_EQ(r.exit_code, 0) << name << ": " << r.output;
    EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  }
}

TEST_F(SecurityAudit, HandEditedGrantWithStarPublishIsRefusedWithSubjectAndTopic) {
  const auto op = pki_->issue("op1", "operator", "saw1");
  resign(op, with_rule(lb::test::read_text(op + "/permissions.xml"), publish("*")));
  const std::string errors = errors_of(files(op));
  EXPECT_NE(errors.find("'CN=op1,O=linebridge'"), std::string::npos) << errors;
  EXPECT_NE(errors.find("publish '*'"), std::string::npos) << errors;
  // The real CLI, as an integrator runs it.
  const auto r = security_check(op);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("CN=op1,O=linebridge"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("'*'"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("ok:"), std::string::npos) << r.output;
}

TEST_F(SecurityAudit, ExtraTopicsAndWildcardsInPublishRightsAreRefused) {
  struct Edit {
    std::string rule, expected;
  };
  const std::vector<Edit> edits{
      {publish("rt/sec/*"), "is a bridge grant (it may publish 'rt/sec/*'"},
      {publish("rt/sec/*/setpoint"), "may publish 'rt/sec/*/setpoint': a wildcard"},
      {publish("rt/sec/saw?/setpoint"), "may publish 'rt/sec/saw?/setpoint': a wildcard"},
      {publish("rt/sec/saw[12]/setpoint"), "may publish 'rt/sec/saw[12]/setpoint': a wildcard"},
      {publish("rq/sec/bridge/commandRequest", "saw*"), "in partition 'saw*': a wildcard"},
      {publish("rq/sec/bridge/nmtRequest", "saw1"),
       "may publish 'rq/sec/bridge/nmtRequest' in partition 'saw1': a right"},
      {publish("rt/other/saw1/setpoint"), "may publish 'rt/other/saw1/setpoint': a right"},
      {publish("rt/sec/saw1/status"), "is a bridge grant (it may publish 'rt/sec/saw1/status'"},
  };
  const auto op = pki_->issue("op1", "operator", "saw1");
  const std::string original = lb::test::read_text(op + "/permissions.xml");
  for (const auto& e : edits) {
    resign(op, with_rule(original, e.rule));
    const std::string errors = errors_of(files(op));
    EXPECT_NE(errors.find(e.expected), std::string::npos) << e.rule << " gave: '" << errors << "'";
    EXPECT_NE(errors.find("CN=op1,O=linebridge"), std::string::npos) << errors;
  }
}

TEST_F(SecurityAudit, ExtraSubscribeRightsAreWarnedNotRefused) {
  const auto obs = pki_->issue("obs1", "observer");
  resign(obs, with_rule(lb::test::read_text(obs + "/permissions.xml"),
                        "        <subscribe><topics><topic>*</topic></topics></subscribe>\n"));
  EXPECT_EQ(errors_of(files(obs)), "");
  const auto warnings = lb::ddsl::grant_warnings(files(obs), kDomain);
  ASSERT_EQ(warnings.size(), 1U);
  EXPECT_NE(warnings[0].find("CN=obs1,O=linebridge"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("may read more than"), std::string::npos) << warnings[0];
  const auto r = security_check(obs);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("warning: "), std::string::npos) << r.output;
}

TEST_F(SecurityAudit, DefaultAllowIsRefused) {
  const auto obs = pki_->issue("obs1", "observer");
  resign(obs, replaced(lb::test::read_text(obs + "/permissions.xml"), "<default>DENY</default>",
                       "<default>ALLOW</default>"));
  EXPECT_NE(errors_of(files(obs)).find("<default>ALLOW</default>"), std::string::npos);
}

TEST_F(SecurityAudit, BridgePermissionsWithASecondBridgeGrantAreRefusedAtCheckAndStart) {
  const std::string bridge = pki_->dir() + "/bridge";
  const std::string xml = lb::test::read_text(bridge + "/permissions.xml");
  const auto begin = xml.find("    <grant ");
  const auto end = xml.find("</grant>") + std::string("</grant>\n").size();
  std::string second = xml.substr(begin, end - begin);
  second = replaced(second, "CN=bridge,O=linebridge", "CN=app,O=linebridge");
  second = replaced(second, "name=\"sec_bridge\"", "name=\"third_party\"");
  resign(bridge, xml.substr(0, end) + second + xml.substr(end));
  const std::string errors = errors_of(files(bridge));
  EXPECT_NE(errors.find("grant 'third_party' for 'CN=app,O=linebridge' is a bridge grant"), std::string::npos)
      << errors;
  EXPECT_EQ(errors.find("'sec_bridge'"), std::string::npos) << "the bridge's own grant is fine\n" << errors;
  const auto check = line_check();
  EXPECT_NE(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("CN=app,O=linebridge"), std::string::npos) << check.output;
  // The bridge's start runs the same check (Participant::create_checked) before any DDS entity.
  lb::ddsl::ParticipantOptions options{kDomain, true, "audit", files(bridge)};
  auto p = lb::ddsl::Participant::create_checked(options);
  ASSERT_FALSE(p);
  EXPECT_TRUE(p.error().configuration);
  EXPECT_NE(p.error().message.find("CN=app,O=linebridge"), std::string::npos) << p.error().message;
}

// ---------------------------------------------------------------------------------------------
// Grants read as Fast DDS 2.9.1 reads them (issue 41): every <topics> and <partitions>, every
// block of a rule together, a rule's domains as Fast DDS matches them, and a document Fast DDS's
// parser refuses. The multi-element grants are hand-edited, signed with pki.sh sign, and given to
// a real Fast DDS participant made without the project's checks: what it lets the identity do is
// what the audit must see.

// Whether Fast DDS itself lets the identity create a writer on `topic` in `partition` ("" = the
// default partition): a participant made straight from the factory with the identity's files.
// nullopt: Fast DDS does not create the participant at all.
std::optional<bool> fast_dds_lets_write(const lb::test::TestPki& pki, const std::string& identity,
                                        const std::string& topic, const std::string& partition) {
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  auto* raw = factory->create_participant(kDomain, lb::ddsl::participant_qos(pki.options(kDomain, identity, "raw")));
  if (raw == nullptr) return std::nullopt;
  fdds::TypeSupport type(new linebridge_msgs::msg::SawSetpointPubSubType());  // TypeSupport owns it
  type.register_type(raw);
  auto* t = raw->create_topic(topic, type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::PublisherQos pq = fdds::PUBLISHER_QOS_DEFAULT;
  if (!partition.empty()) pq.partition().push_back(partition.c_str());
  auto* pub = t ? raw->create_publisher(pq) : nullptr;
  const bool created = pub && pub->create_datawriter(t, fdds::DATAWRITER_QOS_DEFAULT) != nullptr;
  raw->delete_contained_entities();
  factory->delete_participant(raw);
  return created;
}

TEST_F(SecurityAudit, MultiElementGrantsAreReadAsFastDdsReadsThemAndRefused) {
  ASSERT_TRUE(std::getenv("LINEBRIDGE_NETNS") != nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const auto op = pki_->issue("op1", "operator", "saw1");
  const std::string original = lb::test::read_text(op + "/permissions.xml");
  const std::string setpoint_saw1 = "<topic>rt/sec/saw1/setpoint</topic>";
  ASSERT_NE(original.find(setpoint_saw1), std::string::npos) << original;
  struct Edit {
    std::string what, xml;
    std::string topic, partition;  // what Fast DDS lets op1 write with it and not without
    std::string expected;          // the audit's refusal
  };
  const std::vector<Edit> edits{
      {"a second <topics> with a wildcard",
       replaced(original, setpoint_saw1, setpoint_saw1 + "</topics><topics><topic>rt/sec/*/setpoint</topic>"),
       "rt/sec/saw2/setpoint", "", "may publish 'rt/sec/*/setpoint': a wildcard"},
      {"a second <partitions> with a wildcard",
       replaced(original, "<partition>saw1</partition>",
                "<partition>saw1</partition></partitions><partitions><partition>*</partition>"),
       "rq/sec/bridge/commandRequest", "saw2", "may publish 'rq/sec/bridge/commandRequest' in partition '*'"},
      // Within one rule Fast DDS looks a writer's topic up in every <publish>, then its partitions in
      // every <publish>: the set values' block gives the commands the default partition.
      {"a second <publish> in the commands' rule",
       replaced(original, "          </partitions>\n        </publish>",
                "          </partitions>\n        </publish>\n        <publish><topics>" + setpoint_saw1 +
                    "</topics></publish>"),
       "rq/sec/bridge/commandRequest", "", "may publish 'rq/sec/bridge/commandRequest': a right"},
  };
  // The control: the grant pki.sh issued passes, and Fast DDS refuses each of those writers.
  EXPECT_EQ(errors_of(files(op)), "");
  for (const auto& e : edits) {
    EXPECT_EQ(fast_dds_lets_write(*pki_, op, e.topic, e.partition), std::optional<bool>(false))
        << e.topic << " in '" << e.partition << "' with the grant pki.sh issued";
  }
  for (const auto& e : edits) {
    resign(op, e.xml);
    EXPECT_EQ(fast_dds_lets_write(*pki_, op, e.topic, e.partition), std::optional<bool>(true))
        << e.what << ": Fast DDS 2.9.1 was expected to honour it";
    const std::string errors = errors_of(files(op));
    EXPECT_NE(errors.find(e.expected), std::string::npos) << e.what << " gave: '" << errors << "'";
    EXPECT_NE(errors.find("CN=op1,O=linebridge"), std::string::npos) << errors;
    // The real CLI an integrator runs said "ok" to the first two before (issue 41).
    const auto r = security_check(op);
    EXPECT_EQ(r.exit_code, 2) << e.what << ": " << r.output;
    EXPECT_NE(r.output.find(e.expected), std::string::npos) << r.output;
  }
}

TEST_F(SecurityAudit, ARuleOnADomainRangeIsJudgedWhereFastDdsAppliesIt) {
  const auto op = pki_->issue("op1", "operator", "saw1");
  const std::string original = lb::test::read_text(op + "/permissions.xml");
  const std::string domains = "<domains><id>" + std::to_string(kDomain) + "</id></domains>";
  const std::string nmt = "<topic>rq/sec/bridge/commandRequest</topic><topic>rq/sec/bridge/nmtRequest</topic>";
  const std::string with_nmt = replaced(original, "<topic>rq/sec/bridge/commandRequest</topic>", nmt);
  const std::string d = std::to_string(kDomain);
  // Fast DDS (CommonParser.cpp, Permissions.cpp is_domain_in_set): an <id_range> whose <max> is
  // missing or 0 is its <min> alone; <max> first is 0..max.
  for (const std::string& range :
       {"<id_range><min>" + d + "</min><max>0</max></id_range>", "<id_range><min>" + d + "</min></id_range>",
        "<id_range><max>" + d + "</max></id_range>", "<id>99</id><id>" + d + "</id>"}) {
    resign(op, replaced(with_nmt, domains, "<domains>" + range + "</domains>"));
    EXPECT_NE(errors_of(files(op)).find("may publish 'rq/sec/bridge/nmtRequest' in partition 'saw1'"),
              std::string::npos)
        << range << ": '" << errors_of(files(op)) << "'";
  }
  // Ranges that do not reach the line's domain: the rule is another domain's business.
  for (const std::string& range : {"<id_range><min>" + std::to_string(kDomain + 1) + "</min></id_range>",
                                   "<id_range><min>1</min><max>" + std::to_string(kDomain - 1) + "</max></id_range>"}) {
    resign(op, replaced(with_nmt, domains, "<domains>" + range + "</domains>"));
    EXPECT_EQ(errors_of(files(op)).find("nmtRequest"), std::string::npos) << range << ": " << errors_of(files(op));
  }
}

TEST_F(SecurityAudit, ADocumentFastDdsRefusesIsRefusedWithTheElementAndItsLine) {
  ASSERT_TRUE(std::getenv("LINEBRIDGE_NETNS") != nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const auto op = pki_->issue("op1", "operator", "saw1");
  const std::string original = lb::test::read_text(op + "/permissions.xml");
  struct Edit {
    std::string from, to, expected;
  };
  const std::vector<Edit> edits{
      {"<publish>", "<publish><data_tagz/>", "<data_tagz> in <publish>"},
      {"<topic>rt/sec/saw1/setpoint</topic>", "<topics>rt/sec/saw1/setpoint</topics>", "<topics> in <topics>"},
      {"<partition>saw1</partition>", "<partition><!-- saw1 --></partition>", "<partition> without a name"},
      {"<default>DENY</default>", "<default>deny</default>", "<default> must be ALLOW or DENY"},
      {"<default>DENY</default>", "", "where <default> must be"},
      {"<allow_rule>\n        <domains>", "<allow_rule>\n        <publish/><domains>", "must begin with <domains>"},
  };
  for (const auto& e : edits) {
    resign(op, replaced(original, e.from, e.to));
    // Fast DDS itself: no participant with this document.
    EXPECT_EQ(fast_dds_lets_write(*pki_, op, "rt/sec/saw1/setpoint", ""), std::nullopt) << e.to;
    const std::string errors = errors_of(files(op));
    EXPECT_NE(errors.find("Fast DDS 2.9.1 refuses this permissions document"), std::string::npos)
        << e.to << ": '" << errors << "'";
    EXPECT_NE(errors.find(e.expected), std::string::npos) << e.to << ": '" << errors << "'";
    EXPECT_NE(errors.find("(line "), std::string::npos) << errors;
  }
}

TEST_F(SecurityAudit, WhatFastDdsIgnoresOrReadsAsAReadIsWarned) {
  const auto obs = pki_->issue("obs1", "observer");
  const std::string original = lb::test::read_text(obs + "/permissions.xml");
  // <relay>: Fast DDS matches a remote reader on it ("relay only": the samples, not the payload key).
  resign(obs, with_rule(original, "        <relay><topics><topic>rt/sec/*/setpoint</topic></topics></relay>\n"));
  EXPECT_EQ(errors_of(files(obs)), "");
  auto warnings = lb::ddsl::grant_warnings(files(obs), kDomain);
  ASSERT_EQ(warnings.size(), 1U);
  EXPECT_NE(warnings[0].find("may read more than"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("'rt/sec/*/setpoint' (<relay>)"), std::string::npos) << warnings[0];
  // A rule after <default>: never read, so it grants nothing, and the audit says so.
  resign(obs, replaced(original, "<default>DENY</default>",
                       "<default>DENY</default>\n      <allow_rule><domains><id>" + std::to_string(kDomain) +
                           "</id></domains><publish><topics><topic>*</topic></topics></publish></allow_rule>"));
  EXPECT_EQ(errors_of(files(obs)), "");
  warnings = lb::ddsl::grant_warnings(files(obs), kDomain);
  ASSERT_EQ(warnings.size(), 1U);
  EXPECT_NE(warnings[0].find("<allow_rule> after <default>"), std::string::npos) << warnings[0];
  // <data_tags>: Fast DDS 2.9.1 parses it and enforces nothing of it.
  resign(obs, replaced(original, "<subscribe>", "<subscribe><data_tags><tag><name>a</name></tag></data_tags>"));
  EXPECT_EQ(errors_of(files(obs)), "");
  warnings = lb::ddsl::grant_warnings(files(obs), kDomain);
  ASSERT_EQ(warnings.size(), 1U);
  EXPECT_NE(warnings[0].find("<data_tags>"), std::string::npos) << warnings[0];
}

// ---------------------------------------------------------------------------------------------
// Plugin names and dds.sec.* keys.

TEST_F(SecurityAudit, MisspelledPluginNamesAndUnknownKeysAreRefusedBeforeStart) {
  const std::vector<std::pair<std::string, std::string>> bad{
      {"dds.sec.auth.plugin", "builtin.PKI_DH"},
      {"dds.sec.access.plugin", "builtin.Access-Permission"},
      {"dds.sec.crypto.plugin", "builtin.AES-GCM"},
      {"dds.sec.log.plugin", "builtin.DDS_Log"},
      {"dds.sec.auth.builtin.PKI-DH.identity_crls", "file:///x.crl"},
  };
  for (const auto& [key, value] : bad) {
    auto f = files(pki_->dir() + "/bridge");
    f.properties = {{key, value}};
    const std::string errors = errors_of(f);
    EXPECT_NE(errors.find("dds.security.properties " + key), std::string::npos) << key << ": '" << errors << "'";
  }
  auto f = files(pki_->dir() + "/bridge");
  f.properties = {{"dds.sec.auth.builtin.PKI-DH.identity_crls", "file:///x.crl"}};
  EXPECT_NE(errors_of(f).find("did you mean dds.sec.auth.builtin.PKI-DH.identity_crl?"), std::string::npos)
      << errors_of(f);
  // The built-in names and the keys Fast DDS reads pass.
  f.properties = {{"dds.sec.auth.plugin", "builtin.PKI-DH"},
                  {"dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC"},
                  {"dds.sec.log.plugin", "builtin.DDS_LogTopic"},
                  {"dds.sec.log.builtin.DDS_LogTopic.logging_level", "ERROR_LEVEL"}};
  EXPECT_EQ(errors_of(f), "");
  // linebridge --check said ok for a misspelled plugin; now it names it.
  std::ofstream(config_) << line_yaml(pki_->security_yaml() +
                                      "    properties: {dds.sec.crypto.plugin: builtin.AES-GCM}\n");
  const auto check = line_check();
  EXPECT_NE(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("builtin.AES-GCM' is not a plugin"), std::string::npos) << check.output;
}

// ---------------------------------------------------------------------------------------------
// What a participant announces: no fastdds.physical_data.* (host, user, process).

class Announcements : public fdds::DomainParticipantListener {
 public:
  void on_participant_discovery(fdds::DomainParticipant*,
                                eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override {
    if (info.status != eprosima::fastrtps::rtps::ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT) return;
    std::vector<std::string> names;
    for (auto it = info.info.m_properties.begin(); it != info.info.m_properties.end(); ++it)
      names.push_back(it->first());
    std::lock_guard lock(m_);
    seen_[info.info.m_participantName.to_string()] = std::move(names);
  }
  std::optional<std::vector<std::string>> properties_of(const std::string& name) {
    std::lock_guard lock(m_);
    const auto it = seen_.find(name);
    return it == seen_.end() ? std::nullopt : std::optional(it->second);
  }

 private:
  std::mutex m_;
  std::map<std::string, std::vector<std::string>> seen_;
};

std::optional<std::vector<std::string>> wait_for(Announcements& listener, const std::string& name) {
  const auto end = Clock::now() + 20s;
  while (Clock::now() < end) {
    if (auto p = listener.properties_of(name)) return p;
    std::this_thread::sleep_for(20ms);
  }
  return std::nullopt;
}

bool has_physical_data(const std::vector<std::string>& names) {
  return std::any_of(names.begin(), names.end(),
                     [](const std::string& n) { return n.rfind("fastdds.physical_data.", 0) == 0; });
}

TEST(ParticipantAnnouncement, CarriesNoPhysicalData) {
  ASSERT_TRUE(std::getenv("LINEBRIDGE_NETNS") != nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  Announcements listener;
  // The listener: a plain Fast DDS participant on the same QoS conventions (localhost only).
  auto qos = lb::ddsl::participant_qos({kDomain + 1, true, "audit-listener"});
  auto* raw = factory->create_participant(kDomain + 1, qos, &listener, fdds::StatusMask::none());
  ASSERT_NE(raw, nullptr);
  // The control: Fast DDS's default QoS announces them (else this test could not fail).
  auto control_qos = qos;
  control_qos.properties() = fdds::PARTICIPANT_QOS_DEFAULT.properties();
  control_qos.name("audit-control");
  auto* control = factory->create_participant(kDomain + 1, control_qos);
  ASSERT_NE(control, nullptr);
  // The project's participant, as the bridge, the CLI and the tools create theirs.
  auto ours = lb::ddsl::Participant::create({kDomain + 1, true, "audit-ours"});
  ASSERT_TRUE(ours) << ours.error().message;

  const auto control_props = wait_for(listener, "audit-control");
  ASSERT_TRUE(control_props) << "the control participant was never discovered";
  EXPECT_TRUE(has_physical_data(*control_props)) << "Fast DDS's default QoS no longer announces physical data";
  const auto our_props = wait_for(listener, "audit-ours");
  ASSERT_TRUE(our_props) << "the project's participant was never discovered";
  EXPECT_FALSE(has_physical_data(*our_props));

  ours->reset();
  factory->delete_participant(control);
  factory->delete_participant(raw);
}

}  // namespace
