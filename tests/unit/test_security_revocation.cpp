// Revocation and key files, checked before start: the identity CRL (dds.security identity_crl)
// judged as Fast DDS 2.9.1 uses it, launch_scripts/pki.sh revoke, private keys readable by group
// or others, and CA keys beside the identity in use. The PKIs are made here by the real pki.sh and
// openssl; the checks are the ones the bridge, `linebridge --check` and `linebridge-security
// check` run.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>

#include "dds/key_files.hpp"
#include "dds/revocation.hpp"
#include "dds/security_files.hpp"
#include "profiles/line_config.hpp"
#include "support/run_command.hpp"
#include "support/test_pki.hpp"
#include "support/unit_secured_line.hpp"

namespace fs = std::filesystem;

namespace {

constexpr std::uint32_t kDomain = 23;

std::string line_yaml(const std::string& security) {
  return lb::test::secured_line_yaml("rev", kDomain, security,
                                     "buses:\n"
                                     "  - {name: ext, interface: 'virtual:rev', role: master, sync_period_ms: 20}\n"
                                     "devices:\n"
                                     "  - {name: saw1, bus: ext, node_id: 5, profile: cia420-4, version: '3.1'}\n");
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string joined(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += l + "\n";
  return out;
}

// The CRL's next update, as seconds since the epoch (openssl prints it, `date` reads it).
std::time_t crl_time(const std::string& crl, const char* field, const std::string& log) {
  const std::string out = log + ".time";
  lb::test::shell("date -d \"$(openssl crl -noout -" + std::string(field) + " -in '" + crl +
                      "' | cut -d= -f2)\" +%s > '" + out + "'",
                  log);
  return static_cast<std::time_t>(std::stoll(lb::test::read_text(out)));
}

// A certificate's serial as openssl prints it (upper-case hex).
std::string serial_of(const std::string& cert, const std::string& log) {
  const std::string out = log + ".serial";
  lb::test::shell("openssl x509 -noout -serial -in '" + cert + "' | cut -d= -f2 > '" + out + "'", log);
  std::string s = lb::test::read_text(out);
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  return s;
}

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// An identity folder's files copied aside, as the holder of a certificate keeps them.
std::string kept_copy(const std::string& identity, const std::string& to) {
  fs::create_directories(to);
  for (const char* f : {"cert.pem", "key.pem", "permissions.p7s"}) fs::copy_file(identity + "/" + f, to + "/" + f);
  return to;
}

class Revocation : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = lb::test::fresh_test_dir("revocation");
    pki_ = lb::test::pki_for(dir_, line_yaml(""));
    crl_ = pki_->dir() + "/ca/identity_crl.pem";
  }

  // The bridge's files (or an identity's) with this PKI's CRL.
  lb::ddsl::SecurityFiles files(const std::string& identity = "") const {
    auto f = pki_->files(identity.empty() ? pki_->dir() + "/bridge" : identity);
    f.identity_crl = crl_;
    return f;
  }
  std::string check(const lb::ddsl::SecurityFiles& f) const {
    auto r = lb::ddsl::check_security_files(f, kDomain);
    return r ? std::string() : r.error().message;
  }
  // pki.sh with this PKI's folder; its exit code.
  int pki(const std::string& args) const {
    const std::string bin = fs::path(LB_BIN_BRIDGE).parent_path().string();
    return lb::test::shell("LINEBRIDGE_BIN='" + bin + "' '" LB_SOURCE_DIR "/launch_scripts/pki.sh' " + args +
                               " --dir '" + pki_->dir() + "'",
                           pki_->dir() + "/pki.log");
  }
  std::string pki_log() const { return lb::test::read_text(pki_->dir() + "/pki.log"); }
  std::string line_file(const std::string& identity = "") const {
    const std::string path = dir_ + "/line.yaml";
    std::ofstream(path) << line_yaml(pki_->security_yaml(identity));  // with ca/identity_crl.pem
    return path;
  }

  // linebridge-security check and linebridge --check both pass the line file, each with this
  // warning ("warning: ..." and "warning: DDS security: ...").
  void expect_both_checks_warn(const std::string& warning) {
    const std::string line = line_file();
    const auto sec = lb::test::run_command({LB_BIN_SECURITY, "--config", line, "check"});
    EXPECT_EQ(sec.exit_code, 0) << sec.output;
    EXPECT_TRUE(contains(sec.output, "warning: " + warning)) << sec.output;
    const auto bridge = lb::test::run_command({LB_BIN_BRIDGE, "--check", line});
    EXPECT_EQ(bridge.exit_code, 0) << bridge.output;
    EXPECT_TRUE(contains(bridge.output, "warning: DDS security: " + warning)) << bridge.output;
  }

  std::string dir_, crl_;
  std::unique_ptr<lb::test::TestPki> pki_;
};

}  // namespace

// ------------------------------------------------------------------------------------------------
// The line file's key.

TEST(RevocationConfig, IdentityCrlIsAFileKeyAndNotAProperty) {
  const auto registry = lb::profiles::ProfileRegistry::builtin();
  const std::string files =
      "  security:\n"
      "    identity_ca: ca/identity_ca.pem\n    certificate: bridge/cert.pem\n    private_key: bridge/key.pem\n"
      "    permissions_ca: ca/permissions_ca.pem\n    governance: governance.p7s\n    permissions: "
      "bridge/permissions.p7s\n";
  auto with = lb::profiles::parse_line_config(line_yaml(files + "    identity_crl: ca/identity_crl.pem\n"),
                                              "/etc/linebridge/line.yaml", registry);
  ASSERT_TRUE(with) << with.error().message;
  EXPECT_EQ(with->dds.security->identity_crl, "/etc/linebridge/ca/identity_crl.pem");
  auto without = lb::profiles::parse_line_config(line_yaml(files), "/etc/linebridge/line.yaml", registry);
  ASSERT_TRUE(without) << without.error().message;
  EXPECT_EQ(without->dds.security->identity_crl, "") << "no CRL unless the line file names one";
  // The Fast DDS property would bypass the checks: refused, pointing at the key.
  auto prop = lb::profiles::parse_line_config(
      line_yaml(files + "    properties: {dds.sec.auth.builtin.PKI-DH.identity_crl: 'file:///x.pem'}\n"),
      "/etc/linebridge/line.yaml", registry);
  ASSERT_FALSE(prop);
  EXPECT_TRUE(contains(prop.error().message, "names a file: give it with its own dds.security key"))
      << prop.error().message;
}

// ------------------------------------------------------------------------------------------------
// pki.sh's records: revocation by certificate, not by name (issue 41).

TEST_F(Revocation, AReissueWarnsAndRevokeBySerialRevokesThatCertificateOnly) {
  const auto op1 = pki_->issue("op1", "operator", "saw1");
  const std::string first = kept_copy(op1, dir_ + "/op1_first");
  const std::string first_serial = serial_of(first + "/cert.pem", dir_ + "/openssl.log");
  ASSERT_FALSE(first_serial.empty());
  pki_->issue("op1", "operator", "saw1");
  const std::string second_serial = serial_of(op1 + "/cert.pem", dir_ + "/openssl.log");
  ASSERT_NE(first_serial, second_serial);
  EXPECT_TRUE(contains(pki_log(), "warning: op1 was issued before and its earlier certificate(s) stay valid until "
                                  "revoked: serial " +
                                      first_serial))
      << pki_log();
  ASSERT_EQ(pki("list --name op1"), 0) << pki_log();
  EXPECT_TRUE(contains(pki_log(), "valid\t" + first_serial + "\t")) << pki_log();
  EXPECT_TRUE(contains(pki_log(), "valid\t" + second_serial + "\t")) << pki_log();
  // Both are valid until one is revoked: the re-issue alone withdrew nothing.
  EXPECT_EQ(check(files(first)), "");
  EXPECT_EQ(check(files(op1)), "");

  // --serial, written as a person copies it (lower case): the first certificate only.
  ASSERT_EQ(pki("revoke --serial " + lower(first_serial)), 0) << pki_log();
  EXPECT_TRUE(contains(check(files(first)), "it revokes this participant's own certificate")) << check(files(first));
  EXPECT_EQ(check(files(op1)), "") << "the certificate in use must keep working";
  // A serial not in the records, and one revoked already: refused, the CRL untouched.
  const std::string crl_before = lb::test::read_text(crl_);
  EXPECT_EQ(pki("revoke --serial 0123ABCD"), 2);
  EXPECT_TRUE(contains(pki_log(), "revoke: no certificate with serial 0123ABCD in the records")) << pki_log();
  EXPECT_EQ(pki("revoke --serial " + first_serial), 2);
  EXPECT_TRUE(contains(pki_log(), "revoke: serial " + first_serial + " is revoked already")) << pki_log();
  EXPECT_EQ(lb::test::read_text(crl_), crl_before);

  // --name: every certificate of the name not revoked yet (here the second), counted.
  ASSERT_EQ(pki("revoke --name op1"), 0) << pki_log();
  EXPECT_TRUE(contains(pki_log(), "revoked 1 certificate(s) of op1")) << pki_log();
  EXPECT_TRUE(contains(check(files(op1)), "it revokes this participant's own certificate")) << check(files(op1));
  EXPECT_EQ(check(files()), "") << "the bridge must keep working";
}

// A PKI an older pki.sh made signed with `openssl x509 -req` and kept no record: its certificate
// in DIR/NAME/ is recorded before a re-issue replaces it, so revoke --name finds it.
TEST_F(Revocation, ACertificateAnOlderPkiShIssuedIsRecordedBeforeItIsReplaced) {
  const auto op1 = pki_->issue("op1", "operator", "saw1");
  // op1's certificate replaced by one signed as the older pki.sh signed it (same subject, so its
  // grant still applies), not in the records.
  pki_->openssl("req -new -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -sha256 -keyout op1/key.pem "
                "-out op1.csr -subj /O=linebridge/CN=op1");
  pki_->openssl("x509 -req -in op1.csr -CA ca/identity_ca.pem -CAkey ca-private/identity_ca.key "
                "-CAserial ca-private/older.srl -CAcreateserial -days 30 -sha256 -out op1/cert.pem");
  fs::permissions(op1 + "/key.pem", fs::perms::owner_read | fs::perms::owner_write);
  const std::string older = kept_copy(op1, dir_ + "/op1_older");
  const std::string older_serial = serial_of(older + "/cert.pem", dir_ + "/openssl.log");
  EXPECT_EQ(check(files(older)), "");
  ASSERT_EQ(pki("list --name op1"), 0) << pki_log();
  EXPECT_FALSE(contains(pki_log(), older_serial)) << "the test's premise: not in the records\n" << pki_log();

  pki_->issue("op1", "operator", "saw1");
  EXPECT_TRUE(contains(pki_log(), "recorded " + pki_->dir() + "/op1/cert.pem (serial " + older_serial +
                                      "), issued before pki.sh kept records"))
      << pki_log();
  EXPECT_TRUE(contains(pki_log(), "earlier certificate(s) stay valid until revoked")) << pki_log();
  // Three of op1 now: the first pki.sh issued, the older one, the new one.
  ASSERT_EQ(pki("revoke --name op1"), 0) << pki_log();
  EXPECT_TRUE(contains(pki_log(), "revoked 3 certificate(s) of op1")) << pki_log();
  EXPECT_TRUE(contains(check(files(older)), "it revokes this participant's own certificate")) << check(files(older));
  EXPECT_TRUE(contains(check(files(op1)), "it revokes this participant's own certificate")) << check(files(op1));
}

// ------------------------------------------------------------------------------------------------
// The CRL, judged before start.

TEST_F(Revocation, PkiInitMakesAValidEmptyCrlAndKeepsCaKeysAwayFromTheIdentity) {
  EXPECT_TRUE(fs::exists(crl_)) << pki_log();
  EXPECT_EQ(check(files()), "");
  EXPECT_EQ(joined(lb::ddsl::security_warnings(files())), "") << "a fresh pki.sh init should give no warning";
  EXPECT_FALSE(fs::exists(pki_->dir() + "/ca/identity_ca.key"));
  EXPECT_FALSE(fs::exists(pki_->dir() + "/ca/permissions_ca.key"));
  EXPECT_TRUE(fs::exists(pki_->dir() + "/ca-private/identity_ca.key"));
  EXPECT_EQ(fs::status(pki_->dir() + "/ca-private").permissions() & (fs::perms::group_all | fs::perms::others_all),
            fs::perms::none);
  // issue and sign still find the keys.
  const auto op = pki_->issue("op1", "operator", "saw1");
  EXPECT_EQ(check(files(op)), "");
  pki_->sign(op + "/permissions.xml");
}

// A PKI an older pki.sh made, its CA keys in ca/ beside what the bridge reads: init again keeps
// its CAs, finds their keys where that pki.sh left them, issues the CRL and says where the keys
// should go (it failed with "openssl ca -gencrl failed", looking for them in ca-private/ only).
TEST_F(Revocation, PkiInitAgainOnAnOlderLayoutKeepsItsCaAndIssuesTheCrl) {
  const std::string ca = pki_->dir() + "/ca", priv = pki_->dir() + "/ca-private";
  for (const auto& e : fs::directory_iterator(priv)) fs::rename(e.path(), ca + "/" + e.path().filename().string());
  fs::remove(priv);
  fs::remove(crl_);
  const auto ca_before = lb::test::read_text(pki_->identity_ca());
  ASSERT_EQ(pki("init --config '" + dir_ + "/plain.yaml'"), 0) << pki_log();
  EXPECT_TRUE(contains(pki_log(), "the CA keys are in " + ca + ", beside what the bridge reads")) << pki_log();
  EXPECT_EQ(lb::test::read_text(pki_->identity_ca()), ca_before) << "the CA was kept";
  EXPECT_TRUE(fs::exists(crl_)) << pki_log();
  EXPECT_EQ(check(files()), "");
}

TEST_F(Revocation, RevokeRefusesTheRevokedIdentityAndKeepsTheOthers) {
  const auto op1 = pki_->issue("op1", "operator", "saw1");
  const auto op2 = pki_->issue("op2", "operator", "saw1");
  const std::string before = lb::test::read_text(crl_);
  ASSERT_EQ(pki("revoke --name op1"), 0) << pki_log();
  EXPECT_NE(lb::test::read_text(crl_), before) << "the CRL file was not re-issued";
  const std::string refused = check(files(op1));
  EXPECT_TRUE(contains(refused, "identity_crl " + crl_ + ": it revokes this participant's own certificate " + op1 +
                                    "/cert.pem ('CN=op1,O=linebridge'"))
      << refused;
  EXPECT_EQ(check(files(op2)), "") << "another operator must keep working";
  EXPECT_EQ(check(files()), "") << "the bridge must keep working";
  // openssl agrees: op1 revoked, op2 not.
  const std::string ca = pki_->identity_ca();
  EXPECT_NE(lb::test::shell("openssl verify -crl_check -CAfile '" + ca + "' -CRLfile '" + crl_ + "' '" + op1 +
                                "/cert.pem'",
                            dir_ + "/verify.log"),
            0);
  EXPECT_EQ(lb::test::shell("openssl verify -crl_check -CAfile '" + ca + "' -CRLfile '" + crl_ + "' '" + op2 +
                                "/cert.pem'",
                            dir_ + "/verify.log"),
            0)
      << lb::test::read_text(dir_ + "/verify.log");
  // A name that was never issued: refused with a reason, the CRL untouched.
  const std::string after = lb::test::read_text(crl_);
  EXPECT_EQ(pki("revoke --name nobody"), 2);
  EXPECT_TRUE(contains(pki_log(), "revoke: no certificate")) << pki_log();
  EXPECT_EQ(lb::test::read_text(crl_), after);
}

TEST_F(Revocation, ACrlThatFastDdsWouldChokeOnIsRefusedWithItsReason) {
  // Another PKI's CRL: its CA has the same name (pki.sh's default), not the same key.
  lb::test::TestPki other(dir_ + "/plain.yaml", dir_ + "/other");
  auto f = files();
  f.identity_crl = other.dir() + "/ca/identity_crl.pem";
  std::string r = check(f);
  EXPECT_TRUE(
      contains(r, "identity_crl " + f.identity_crl + ": its signature does not verify with the key of the identity CA"))
      << r;
  // Not a CRL, and a missing file.
  f.identity_crl = pki_->identity_ca();
  r = check(f);
  EXPECT_TRUE(contains(r, "identity_crl " + f.identity_crl + ": no PEM certificate revocation list in it")) << r;
  f.identity_crl = dir_ + "/missing.pem";
  r = check(f);
  EXPECT_TRUE(contains(r, "identity_crl " + f.identity_crl + ": cannot read it: No such file or directory")) << r;
  // The participant's own certificate revoked: Fast DDS would refuse its own identity.
  ASSERT_EQ(pki("revoke --name bridge"), 0) << pki_log();  // now the bridge's own certificate is revoked
  r = check(files());
  EXPECT_TRUE(contains(r, "it revokes this participant's own certificate")) << r;
}

TEST_F(Revocation, NextUpdateNearIsAWarningAndPastIsAProblem) {
  const std::time_t last = crl_time(crl_, "lastupdate", dir_ + "/date");
  const std::time_t next = crl_time(crl_, "nextupdate", dir_ + "/date");
  ASSERT_GT(next, last);
  const auto at = [&](std::time_t now) {
    return lb::ddsl::check_identity_crl(crl_, pki_->identity_ca(), pki_->dir() + "/bridge/cert.pem", now);
  };
  auto now = at(last + 60);
  EXPECT_TRUE(now.problems.empty() && now.warnings.empty());
  auto soon = at(next - 3 * 24 * 3600);
  ASSERT_TRUE(soon.problems.empty());
  ASSERT_EQ(soon.warnings.size(), 1u);
  EXPECT_TRUE(contains(soon.warnings[0].text(), "identity_crl " + crl_ + ": its next update is "))
      << soon.warnings[0].text();
  EXPECT_TRUE(contains(soon.warnings[0].text(), "within 7 days")) << soon.warnings[0].text();
  EXPECT_TRUE(at(next - 8 * 24 * 3600).warnings.empty()) << "8 days ahead is not near";
  auto past = at(next + 60);
  ASSERT_EQ(past.problems.size(), 1u);
  EXPECT_TRUE(contains(past.problems[0].why, "expired: its next update was")) << past.problems[0].why;
  auto early = at(last - 3600);
  ASSERT_EQ(early.problems.size(), 1u);
  EXPECT_TRUE(contains(early.problems[0].why, "not valid before")) << early.problems[0].why;
}

TEST_F(Revocation, BothPreflightChecksPrintTheNextUpdateWarning) {
  ASSERT_EQ(pki("revoke --days 3"), 0) << pki_log();  // re-issued, valid 3 days only
  expect_both_checks_warn("identity_crl " + crl_ + ": its next update is ");
}

// ------------------------------------------------------------------------------------------------
// Key files.

TEST_F(Revocation, AKeyReadableByGroupOrOthersIsRefusedWithItsMode) {
  const auto op = pki_->issue("op1", "operator", "saw1");
  const std::string key = op + "/key.pem";
  ASSERT_EQ(::chmod(key.c_str(), 0644), 0);
  std::string r = check(files(op));
  EXPECT_TRUE(contains(r, "private_key " + key + ": mode 0644 gives group or others access")) << r;
  ASSERT_EQ(::chmod(key.c_str(), 0640), 0);
  EXPECT_TRUE(contains(check(files(op)), "mode 0640"));
  // linebridge-security check --identity: the client's key, exit 2.
  const std::string line = line_file();
  const auto client = lb::test::run_command({LB_BIN_SECURITY, "--config", line, "check", "--identity", op});
  EXPECT_EQ(client.exit_code, 2) << client.output;
  EXPECT_TRUE(contains(client.output, "private_key " + key + ": mode 0640")) << client.output;
  // The bridge's own: --check refuses as well (exit 2).
  const std::string bridge_key = pki_->dir() + "/bridge/key.pem";
  ASSERT_EQ(::chmod(bridge_key.c_str(), 0604), 0);
  const auto bridge = lb::test::run_command({LB_BIN_BRIDGE, "--check", line});
  EXPECT_EQ(bridge.exit_code, 2) << bridge.output;
  EXPECT_TRUE(contains(bridge.output, "private_key " + bridge_key + ": mode 0604")) << bridge.output;
  // The control: owner-only passes.
  ASSERT_EQ(::chmod(key.c_str(), 0600), 0);
  ASSERT_EQ(::chmod(bridge_key.c_str(), 0400), 0);
  EXPECT_EQ(check(files(op)), "");
  EXPECT_EQ(check(files()), "");
}

TEST_F(Revocation, CaKeysBesideTheIdentityInUseAreFlagged) {
  const std::string bridge = pki_->dir() + "/bridge";
  ASSERT_EQ(joined(lb::ddsl::security_warnings(files())), "");
  // A copy of the identity CA's key under an innocent name in the bridge's folder: matched by key.
  fs::copy_file(pki_->dir() + "/ca-private/identity_ca.key", bridge + "/backup.pem");
  // The layout an older pki.sh left: ca/*.key beside the CA certificates the bridge reads.
  fs::copy_file(pki_->dir() + "/ca-private/permissions_ca.key", pki_->dir() + "/ca/permissions_ca.key");
  // Not a CA key: another identity's key in the bridge's folder is not flagged.
  fs::copy_file(pki_->issue("op1", "operator", "saw1") + "/key.pem", bridge + "/op1.key");
  const std::string w = joined(lb::ddsl::security_warnings(files()));
  EXPECT_TRUE(contains(w, "CA key " + bridge +
                              "/backup.pem: the private key of the CA 'CN=identity CA,O=linebridge' lies beside"))
      << w;
  EXPECT_TRUE(
      contains(w, "CA key " + pki_->dir() + "/ca/permissions_ca.key: the private key of the CA 'CN=permissions CA"))
      << w;
  EXPECT_FALSE(contains(w, "op1.key")) << w;
  EXPECT_EQ(check(files()), "") << "a CA key beside the identity is a warning, not a refusal";
  // Both pre-flight checks say it.
  expect_both_checks_warn("CA key " + bridge + "/backup.pem");
}
