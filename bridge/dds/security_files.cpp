#include "dds/security_files.hpp"
#include "dds/openssl_ptr.hpp"

#include "dds/key_files.hpp"
#include "dds/revocation.hpp"

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/objects.h>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>
#include <tinyxml2.h>

#include "dds/governance_audit.hpp"
#include "dds/security_properties.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <memory>
#include <optional>
#include <sstream>
#include <system_error>

namespace lb::ddsl {
namespace {

// OpenSSL objects owned by unique_ptr (openssl_ptr.hpp).
using Bio = ossl::Bio;
using Cert = ossl::Cert;
using Store = ossl::Store;
using StoreCtx = ossl::StoreCtx;
using Key = ossl::Key;
using Pkcs7 = std::unique_ptr<PKCS7, ossl::Free<PKCS7_free>>;
struct FreeCertStack {
  void operator()(STACK_OF(X509) * s) const { sk_X509_free(s); }  // the certificates belong to the PKCS7
};
using CertStack = std::unique_ptr<STACK_OF(X509), FreeCertStack>;

// One line per problem: "<key> <path>: <reason>".
class Problems {
 public:
  void add(const std::string& key, const std::string& path, const std::string& why) {
    lines_.push_back(key + " " + path + ": " + why);
  }
  bool empty() const { return lines_.empty(); }
  Result<void> result() const {
    if (lines_.empty()) return {};
    std::string text = "DDS security: " + std::to_string(lines_.size()) + " problem(s):";
    for (const auto& l : lines_) text += "\n  " + l;
    return make_error(text);
  }

 private:
  std::vector<std::string> lines_;
};

// The readers openssl_ptr.hpp shares with the revocation and key-file checks.
using ossl::bio_text;
using ossl::memory_bio;
using ossl::read_certificates;
using ossl::time_text;
constexpr auto& read_file = ossl::read_whole_file;

std::string openssl_error() {
  const unsigned long e = ERR_peek_last_error();
  ERR_clear_error();
  if (e == 0) return "no reason given";
  char buf[256];
  ERR_error_string_n(e, buf, sizeof buf);
  return buf;
}

// As Fast DDS prints it (PKIDH.cpp): RFC 2253 order, most specific first.
std::string subject_of(X509* cert) { return ossl::name_text(X509_get_subject_name(cert)); }

// Two CAs may carry the same name: the fingerprint tells them apart in a message.
std::string fingerprint(X509* cert) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  X509_digest(cert, EVP_sha256(), md, &n);
  std::string out = "SHA-256 ";
  char hex[4];
  for (unsigned int i = 0; i < n && i < 8; ++i) {
    std::snprintf(hex, sizeof hex, "%02X%s", md[i], i + 1 < 8 ? ":" : "");
    out += hex;
  }
  return out + "...";
}

Store store_of(const std::vector<Cert>& cas) {
  Store store(X509_STORE_new());
  for (const auto& c : cas) X509_STORE_add_cert(store.get(), c.get());
  return store;
}

// X509_V_OK or the reason the chain does not verify, with Fast DDS's flags (PKIDH.cpp).
int verify_chain(X509* cert, const std::vector<Cert>& cas) {
  Store store = store_of(cas);
  StoreCtx ctx(X509_STORE_CTX_new());
  if (X509_STORE_CTX_init(ctx.get(), store.get(), cert, nullptr) != 1) return X509_V_ERR_UNSPECIFIED;
  X509_STORE_CTX_set_flags(ctx.get(), X509_V_FLAG_CHECK_SS_SIGNATURE | X509_V_FLAG_POLICY_CHECK);
  if (X509_verify_cert(ctx.get()) == 1) return X509_V_OK;
  return X509_STORE_CTX_get_error(ctx.get());
}

std::optional<std::string> validity_problem(X509* cert) {
  if (X509_cmp_current_time(X509_get0_notAfter(cert)) < 0) return "expired on " + time_text(X509_get0_notAfter(cert));
  if (X509_cmp_current_time(X509_get0_notBefore(cert)) > 0) {
    return "not valid before " + time_text(X509_get0_notBefore(cert));
  }
  return std::nullopt;
}

// Fast DDS 2.9 takes identities signed with these only (Permissions.cpp, PKIDH.cpp).
std::optional<std::string> signature_problem(X509* cert) {
  const int nid = X509_get_signature_nid(cert);
  if (nid == NID_ecdsa_with_SHA256 || nid == NID_sha256WithRSAEncryption || nid == NID_sha1WithRSAEncryption) {
    return std::nullopt;
  }
  return std::string("signed with ") + OBJ_nid2ln(nid) +
         ": Fast DDS 2.9 accepts only ecdsa-with-SHA256 and sha256WithRSAEncryption";
}

// ---------------------------------------------------------------------------------------------
// Certificates and key.

struct Identity {
  std::vector<Cert> cas;
  Cert cert;
};

std::vector<Cert> check_ca(const std::string& key, const std::string& path, Problems& problems) {
  std::string why;
  auto pem = read_file(path, why);
  if (!pem) return problems.add(key, path, why), std::vector<Cert>{};
  auto cas = read_certificates(*pem);
  if (cas.empty()) return problems.add(key, path, "no PEM certificate in it"), std::vector<Cert>{};
  for (const auto& ca : cas) {
    if (auto v = validity_problem(ca.get()))
      problems.add(key, path, "CA certificate '" + subject_of(ca.get()) + "' " + *v);
  }
  return cas;
}

Cert check_certificate(const SecurityFiles& f, const std::vector<Cert>& cas, Problems& problems) {
  std::string why;
  auto pem = read_file(f.certificate, why);
  if (!pem) return problems.add("certificate", f.certificate, why), nullptr;
  auto certs = read_certificates(*pem);
  if (certs.empty()) return problems.add("certificate", f.certificate, "no PEM certificate in it"), nullptr;
  Cert cert = std::move(certs.front());
  const std::string subject = "'" + subject_of(cert.get()) + "'";
  if (auto v = validity_problem(cert.get())) problems.add("certificate", f.certificate, subject + " " + *v);
  if (auto s = signature_problem(cert.get())) problems.add("certificate", f.certificate, subject + " " + *s);
  if (!cas.empty()) {
    const int err = verify_chain(cert.get(), cas);
    if (err != X509_V_OK && err != X509_V_ERR_CERT_HAS_EXPIRED && err != X509_V_ERR_CERT_NOT_YET_VALID) {
      Bio out(BIO_new(BIO_s_mem()));
      X509_NAME_print_ex(out.get(), X509_get_issuer_name(cert.get()), 0, XN_FLAG_RFC2253 & ~ASN1_STRFLGS_ESC_MSB);
      problems.add("certificate", f.certificate,
                   subject + " is not accepted by the identity CA " + f.identity_ca + " ('" +
                       subject_of(cas.front().get()) + "', " + fingerprint(cas.front().get()) +
                       "): " + X509_verify_cert_error_string(err) + " (it was issued by a CA named '" +
                       bio_text(out.get()) + "')");
    }
  }
  return cert;
}

std::string password_of(const SecurityFiles& f) {
  for (const auto& [k, v] : f.properties) {
    if (k == "dds.sec.auth.builtin.PKI-DH.password") return v;
  }
  return {};
}

void check_private_key(const SecurityFiles& f, X509* cert, Problems& problems) {
  std::string why;
  auto pem = read_file(f.private_key, why);
  if (!pem) return problems.add("private_key", f.private_key, why);
  Bio in = memory_bio(*pem);
  std::string password = password_of(f);
  Key key(PEM_read_bio_PrivateKey(in.get(), nullptr, nullptr, password.empty() ? nullptr : password.data()));
  if (!key) {
    return problems.add("private_key", f.private_key,
                        "not a PEM private key, or encrypted without the right password (" + openssl_error() + ")");
  }
  if (cert != nullptr && X509_check_private_key(cert, key.get()) != 1) {
    ERR_clear_error();
    problems.add("private_key", f.private_key,
                 "does not belong to the certificate " + f.certificate + " ('" + subject_of(cert) + "')");
  }
}

// ---------------------------------------------------------------------------------------------
// Signed documents (governance, permissions): S/MIME signed by the permissions CA with `-text`,
// verified as Fast DDS does (Permissions.cpp: PKCS7_verify with PKCS7_TEXT against the CA).

const char* const kSignHint =
    "openssl smime -sign -text -in FILE.xml -out FILE.p7s -signer permissions_ca.pem -inkey permissions_ca.key";

struct Parsed {
  Pkcs7 p7;
  Bio content;
};

Parsed parse_smime(const std::string& bytes) {
  Bio in = memory_bio(bytes);
  BIO* content = nullptr;
  Pkcs7 p7(SMIME_read_PKCS7(in.get(), &content));
  return {std::move(p7), Bio(content)};
}

bool verifies(const std::string& bytes, const std::vector<Cert>& cas, int flags, std::string* out_text) {
  Parsed p = parse_smime(bytes);
  if (!p.p7) return false;
  Store store = store_of(cas);
  Bio out(BIO_new(BIO_s_mem()));
  const bool ok = PKCS7_verify(p.p7.get(), nullptr, store.get(), p.content.get(), out.get(), flags) == 1;
  ERR_clear_error();
  if (ok && out_text != nullptr) *out_text = bio_text(out.get());
  return ok;
}

std::optional<std::string> signed_content(const std::string& key, const std::string& path, const std::vector<Cert>& cas,
                                          const std::string& ca_path, Problems& problems) {
  std::string why;
  auto bytes = read_file(path, why);
  if (!bytes) return problems.add(key, path, why), std::nullopt;
  Parsed parsed = parse_smime(*bytes);
  ERR_clear_error();
  if (!parsed.p7) {
    const bool xml = bytes->find("<dds") != std::string::npos || bytes->find("<?xml") != std::string::npos;
    problems.add(key, path,
                 std::string(xml ? "an unsigned XML document" : "not an S/MIME signed document") +
                     ": Fast DDS takes only documents signed by the permissions CA (" + kSignHint + ")");
    return std::nullopt;
  }
  if (cas.empty()) return std::nullopt;  // the permissions CA's own problem is reported already
  std::string content;
  if (verifies(*bytes, cas, PKCS7_TEXT, &content)) return content;

  // Why not: another signer, a CA that cannot sign, no text header, or changed content.
  CertStack signers(PKCS7_get0_signers(parsed.p7.get(), nullptr, 0));
  ERR_clear_error();
  X509* signer = (signers && sk_X509_num(signers.get()) > 0) ? sk_X509_value(signers.get(), 0) : nullptr;
  const bool from_ca = signer != nullptr && std::any_of(cas.begin(), cas.end(), [&](const Cert& ca) {
                         return X509_cmp(ca.get(), signer) == 0 || X509_check_issued(ca.get(), signer) == X509_V_OK;
                       });
  if (!from_ca) {
    problems.add(key, path,
                 "signed by '" +
                     (signer ? subject_of(signer) + "' (" + fingerprint(signer) + ")"
                             : std::string("an unknown signer'")) +
                     ", not by the permissions CA " + ca_path + " ('" + subject_of(cas.front().get()) + "', " +
                     fingerprint(cas.front().get()) + ")");
    return std::nullopt;
  }
  if (verifies(*bytes, cas, PKCS7_TEXT | PKCS7_NOVERIFY, nullptr)) {
    const int err = verify_chain(signer, cas);
    std::string reason = err == X509_V_OK ? std::string("the signer cannot sign documents")
                                          : X509_verify_cert_error_string(err);
    if ((X509_get_extension_flags(signer) & EXFLAG_KUSAGE) != 0 &&
        (X509_get_key_usage(signer) & (KU_DIGITAL_SIGNATURE | KU_NON_REPUDIATION)) == 0) {
      reason = "the signing certificate '" + subject_of(signer) + "' has a keyUsage without digitalSignature";
    }
    problems.add(key, path, "its signature is not accepted: " + reason);
    return std::nullopt;
  }
  if (verifies(*bytes, cas, PKCS7_NOVERIFY, nullptr)) {
    problems.add(key, path,
                 "signed without -text: Fast DDS 2.9 verifies the text/plain header that `openssl smime -sign -text` "
                 "adds (" +
                     std::string(kSignHint) + ")");
    return std::nullopt;
  }
  problems.add(key, path, "its signature does not match its content: the document was changed after it was signed");
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// Document contents, read as Fast DDS's parsers read them.

using tinyxml2::XMLElement;

std::string text_of(const XMLElement* e) { return e != nullptr && e->GetText() != nullptr ? e->GetText() : ""; }

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

// <domains><id>N</id><id_range><min>a</min><max>b</max></id_range></domains>
bool domain_in(const XMLElement* domains, std::uint32_t domain) {
  if (domains == nullptr) return false;
  for (const XMLElement* e = domains->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
    if (std::string(e->Name()) == "id") {
      if (e->UnsignedText(0xffffffffU) == domain) return true;
    } else if (std::string(e->Name()) == "id_range") {
      const XMLElement* lo = e->FirstChildElement("min");
      const XMLElement* hi = e->FirstChildElement("max");
      const unsigned min = lo ? lo->UnsignedText(0) : 0;
      const unsigned max = hi ? hi->UnsignedText(0xffffffffU) : 0xffffffffU;
      if (domain >= min && domain <= max) return true;
    }
  }
  return false;
}

bool bool_text(const XMLElement* e, bool fallback) {
  bool v = fallback;
  if (e != nullptr) e->QueryBoolText(&v);
  return v;
}

// The product's promise: nobody joins unauthenticated, every topic's readers and writers need a
// grant, every payload is encrypted. SIGN is not an option: broken in Fast DDS 2.9.1 for payloads
// whose size is not a multiple of 4.
void check_governance(const std::string& path, const std::string& xml, std::uint32_t domain, Problems& problems) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) {
    return problems.add("governance", path, std::string("malformed XML: ") + doc.ErrorStr());
  }
  const XMLElement* rules = doc.FirstChildElement("dds")
                                ? doc.FirstChildElement("dds")->FirstChildElement("domain_access_rules")
                                : nullptr;
  if (rules == nullptr) return problems.add("governance", path, "no <dds><domain_access_rules> in it");
  const XMLElement* rule = rules->FirstChildElement("domain_rule");
  while (rule != nullptr && !domain_in(rule->FirstChildElement("domains"), domain))
    rule = rule->NextSiblingElement("domain_rule");
  if (rule == nullptr)
    return problems.add("governance", path, "no domain_rule covers domain " + std::to_string(domain));
  const std::string where = "the domain_rule of domain " + std::to_string(domain);
  if (bool_text(rule->FirstChildElement("allow_unauthenticated_participants"), true)) {
    problems.add("governance", path,
                 where + " allows unauthenticated participants (allow_unauthenticated_participants must be false)");
  }
  if (!bool_text(rule->FirstChildElement("enable_join_access_control"), false)) {
    problems.add("governance", path, where + " does not control who joins (enable_join_access_control must be true)");
  }
  const XMLElement* topics = rule->FirstChildElement("topic_access_rules");
  int n = 0;
  for (const XMLElement* t = topics ? topics->FirstChildElement("topic_rule") : nullptr; t != nullptr;
       t = t->NextSiblingElement("topic_rule")) {
    ++n;
    const std::string topic = "topic_rule '" + trimmed(text_of(t->FirstChildElement("topic_expression"))) + "'";
    if (!bool_text(t->FirstChildElement("enable_read_access_control"), false) ||
        !bool_text(t->FirstChildElement("enable_write_access_control"), false)) {
      problems.add("governance", path,
                   topic + " lets anyone read or write (enable_read_access_control and "
                           "enable_write_access_control must be true)");
    }
    const std::string data = trimmed(text_of(t->FirstChildElement("data_protection_kind")));
    if (data.rfind("SIGN", 0) == 0) {
      problems.add("governance", path,
                   topic + ": data_protection_kind " + data +
                       " is broken in Fast DDS 2.9.1 (payloads whose size is not a multiple of 4 "
                       "never arrive): use ENCRYPT");
    } else if (data.rfind("ENCRYPT", 0) != 0) {
      problems.add("governance", path,
                   topic + ": data_protection_kind " + (data.empty() ? "(none)" : data) +
                       " leaves payloads readable on the wire: use ENCRYPT");
    }
  }
  if (n == 0) problems.add("governance", path, where + " has no topic_rule");
}

std::vector<std::string> split_subject(const std::string& s, char sep) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(s);
  while (std::getline(in, part, sep)) {
    part = trimmed(part);
    if (!part.empty()) parts.push_back(part);
  }
  return parts;
}

// "YYYY-MM-DDThh:mm:ss" in the host's local time zone, as Fast DDS reads it (PermissionsParser.cpp).
std::optional<std::time_t> local_time(const std::string& text) {
  std::tm tm{};
  std::istringstream in(trimmed(text));
  in >> std::get_time(&tm, "%Y-%m-%dT%H:%M:%S");
  if (in.fail()) return std::nullopt;
  tm.tm_isdst = -1;
  return std::mktime(&tm);
}

void check_permissions(const SecurityFiles& f, const std::string& xml, const std::string& subject, std::uint32_t domain,
                       Problems& problems) {
  const std::string& path = f.permissions;
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) {
    return problems.add("permissions", path, std::string("malformed XML: ") + doc.ErrorStr());
  }
  const XMLElement* perms = doc.FirstChildElement("dds")
                                ? doc.FirstChildElement("dds")->FirstChildElement("permissions")
                                : nullptr;
  if (perms == nullptr) return problems.add("permissions", path, "no <dds><permissions> in it");
  if (subject.empty()) return;  // the certificate's own problem is reported already

  const auto wanted = split_subject(subject, ',');
  auto sorted_wanted = wanted;
  std::sort(sorted_wanted.begin(), sorted_wanted.end());
  std::vector<std::string> reasons;
  std::vector<std::string> others;
  const std::time_t now = std::time(nullptr);
  for (const XMLElement* g = perms->FirstChildElement("grant"); g != nullptr; g = g->NextSiblingElement("grant")) {
    const std::string name = g->Attribute("name") ? g->Attribute("name") : "";
    const std::string grant_subject = trimmed(text_of(g->FirstChildElement("subject_name")));
    const bool slash = !grant_subject.empty() && grant_subject.front() == '/';
    auto parts = split_subject(grant_subject, slash ? '/' : ',');
    const std::string grant = "grant '" + name + "'";
    if (parts != wanted) {
      std::sort(parts.begin(), parts.end());
      if (parts == sorted_wanted) {
        reasons.push_back(grant + " names the certificate's subject as '" + grant_subject +
                          "', which is not in RFC 2253 order (as `openssl x509 -noout -subject -nameopt RFC2253` "
                          "prints it; Fast DDS compares in that order): write '" +
                          subject + "'");
      } else {
        others.push_back("'" + grant_subject + "'");
      }
      continue;
    }
    const XMLElement* validity = g->FirstChildElement("validity");
    const std::string nb = text_of(validity ? validity->FirstChildElement("not_before") : nullptr);
    const std::string na = text_of(validity ? validity->FirstChildElement("not_after") : nullptr);
    const auto not_before = local_time(nb);
    const auto not_after = local_time(na);
    if (!not_before || !not_after) {
      reasons.push_back(grant + " has no readable validity (not_before/not_after as YYYY-MM-DDThh:mm:ss)");
      continue;
    }
    if (now > *not_after) {
      reasons.push_back(grant + " expired at " + trimmed(na) + " (host local time, as Fast DDS reads it)");
      continue;
    }
    if (now < *not_before) {
      reasons.push_back(grant + " is not valid before " + trimmed(nb) + " (host local time, as Fast DDS reads it)");
      continue;
    }
    bool covers = false;
    for (const XMLElement* r = g->FirstChildElement(); r != nullptr && !covers; r = r->NextSiblingElement()) {
      const std::string kind = r->Name();
      if (kind == "allow_rule") covers = domain_in(r->FirstChildElement("domains"), domain);
    }
    if (!covers) {
      reasons.push_back(grant + " allows nothing on domain " + std::to_string(domain));
      continue;
    }
    return;  // Fast DDS takes the first grant that is in force for the subject
  }
  if (reasons.empty()) {
    std::string listed;
    for (const auto& o : others) listed += (listed.empty() ? "" : ", ") + o;
    reasons.push_back("no grant for the certificate's subject '" + subject + "' (" + f.certificate + ")" +
                      (listed.empty() ? std::string(": it has no grant") : "; its grants are for " + listed));
  }
  for (const auto& r : reasons) problems.add("permissions", path, r);
}

}  // namespace

Result<std::string> certificate_subject(const std::string& certificate_path) {
  std::string why;
  auto pem = read_file(certificate_path, why);
  if (!pem) return make_error(certificate_path + ": " + why);
  auto certs = read_certificates(*pem);
  if (certs.empty()) return make_error(certificate_path + ": no PEM certificate in it");
  return subject_of(certs.front().get());
}

Result<void> check_security_files(const SecurityFiles& f, std::uint32_t domain) {
  Problems problems;
  const auto identity_cas = check_ca("identity_ca", f.identity_ca, problems);
  Cert cert = check_certificate(f, identity_cas, problems);
  check_private_key(f, cert.get(), problems);
  if (auto mode = private_key_mode_problem(f.private_key)) problems.add("private_key", f.private_key, *mode);
  if (!f.identity_crl.empty()) {
    for (const auto& p :
         check_identity_crl(f.identity_crl, f.identity_ca, f.certificate, std::time(nullptr)).problems) {
      problems.add(p.key, p.path, p.why);
    }
  }
  const auto permission_cas = check_ca("permissions_ca", f.permissions_ca, problems);
  if (auto xml = signed_content("governance", f.governance, permission_cas, f.permissions_ca, problems)) {
    check_governance(f.governance, *xml, domain, problems);
    for (const auto& p : governance_protection_problems(*xml, domain)) problems.add("governance", f.governance, p);
  }
  if (auto xml = signed_content("permissions", f.permissions, permission_cas, f.permissions_ca, problems)) {
    check_permissions(f, *xml, cert ? subject_of(cert.get()) : std::string(), domain, problems);
    if (f.grant_policy) {
      for (const auto& e : audit_grants(*xml, *f.grant_policy, domain).errors)
        problems.add("permissions", f.permissions, e);
    }
  }
  for (const auto& [key, why] : security_property_problems(f.properties))
    problems.add("dds.security.properties", key, why);
  return problems.result();
}

std::vector<std::string> security_warnings(const SecurityFiles& f) {
  std::vector<std::string> out;
  if (!f.identity_crl.empty()) {
    for (const auto& w :
         check_identity_crl(f.identity_crl, f.identity_ca, f.certificate, std::time(nullptr)).warnings) {
      out.push_back(w.text());
    }
  }
  const std::vector<std::string> in_use{f.identity_ca, f.certificate, f.private_key, f.permissions_ca,
                                        f.governance,  f.permissions, f.identity_crl};
  for (const auto& w : ca_keys_beside(in_use, {f.identity_ca, f.permissions_ca}, f.private_key))
    out.push_back(w.text());
  return out;
}

}  // namespace lb::ddsl
