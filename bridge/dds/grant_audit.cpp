#include "dds/grant_audit.hpp"

#include <fnmatch.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pkcs7.h>
#include <openssl/x509.h>
#include <tinyxml2.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <set>

#include "base/bounded_file.hpp"
#include "dds/openssl_ptr.hpp"
#include "dds/participant.hpp"  // reply_topic
#include "dds/security_files.hpp"
#include "dds/security_policy.hpp"
#include "dds/topic_names.hpp"
#include "dds/xml_rules.hpp"

namespace lb::ddsl {
namespace {

using tinyxml2::XMLElement;

// One right: a topic (expression) in one partition ("" = the default partition only).
struct Right {
  std::string topic;
  std::string partition;
  // NOLINTNEXTLINE(modernize-use-nullptr): clang-tidy 14 misreads a defaulted <=>
  auto operator<=>(const Right&) const = default;
};

struct ParsedGrant {
  std::string name;
  std::string subject;
  bool default_allow = false;
  std::set<Right> publish;
  std::set<Right> subscribe;
};

using xml::covers;
using xml::trimmed_text;

std::vector<std::string> texts(const XMLElement* list, const char* item) {
  std::vector<std::string> out;
  for (const XMLElement* e = list ? list->FirstChildElement(item) : nullptr; e != nullptr;
       e = e->NextSiblingElement(item)) {
    out.push_back(trimmed_text(e));
  }
  return out;
}

// Each <publish>/<subscribe> of the allow rules on `domain` as (topic, partition) pairs. Deny
// rules only take rights away: they are not needed to judge what a grant may at most do.
void add_rights(const XMLElement* block, std::set<Right>& rights) {
  auto partitions = texts(block->FirstChildElement("partitions"), "partition");
  if (partitions.empty()) partitions.emplace_back();
  for (const auto& topic : texts(block->FirstChildElement("topics"), "topic")) {
    for (const auto& partition : partitions) rights.insert({topic, partition});
  }
}

std::optional<std::vector<ParsedGrant>> parse_grants(const std::string& xml, std::uint32_t domain) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) return std::nullopt;
  const XMLElement* dds = doc.FirstChildElement("dds");
  const XMLElement* perms = dds ? dds->FirstChildElement("permissions") : nullptr;
  if (perms == nullptr) return std::nullopt;
  std::vector<ParsedGrant> grants;
  for (const XMLElement* g = perms->FirstChildElement("grant"); g != nullptr; g = g->NextSiblingElement("grant")) {
    ParsedGrant grant;
    grant.name = g->Attribute("name") ? g->Attribute("name") : "";
    grant.subject = trimmed_text(g->FirstChildElement("subject_name"));
    grant.default_allow = trimmed_text(g->FirstChildElement("default")) == "ALLOW";
    for (const XMLElement* r = g->FirstChildElement("allow_rule"); r != nullptr;
         r = r->NextSiblingElement("allow_rule")) {
      if (!covers(r->FirstChildElement("domains"), domain)) continue;
      for (const XMLElement* b = r->FirstChildElement("publish"); b != nullptr; b = b->NextSiblingElement("publish")) {
        add_rights(b, grant.publish);
      }
      for (const XMLElement* b = r->FirstChildElement("subscribe"); b != nullptr;
           b = b->NextSiblingElement("subscribe")) {
        add_rights(b, grant.subscribe);
      }
    }
    grants.push_back(std::move(grant));
  }
  return grants;
}

// What `linebridge-security permissions` writes for a role: the very same generator, parsed back.
struct Reference {
  std::set<Right> publish;
  std::set<Right> subscribe;
};

void add_generated(Reference& ref, const GrantPolicy& policy, std::uint32_t domain, Role role,
                   std::vector<std::string> devices) {
  Grant g;
  g.line = policy.line;
  g.domain = domain;
  g.subject = "CN=reference";
  g.role = role;
  g.devices = std::move(devices);
  g.not_before = "2000-01-01T00:00:00";
  g.not_after = "2000-01-02T00:00:00";
  auto parsed = parse_grants(permissions_xml(g), domain);
  if (!parsed || parsed->empty()) return;
  ref.publish.insert(parsed->front().publish.begin(), parsed->front().publish.end());
  ref.subscribe.insert(parsed->front().subscribe.begin(), parsed->front().subscribe.end());
}

// The widest grant pki.sh issues for the role: every device of the line, and for an engineer
// also the one issued without --devices (every device, present and future: "*").
Reference reference(const GrantPolicy& policy, std::uint32_t domain, Role role) {
  Reference ref;
  switch (role) {
    case Role::observer:
    case Role::bridge: add_generated(ref, policy, domain, role, {}); break;
    case Role::operator_: add_generated(ref, policy, domain, role, policy.devices); break;
    case Role::engineer:
      add_generated(ref, policy, domain, role, policy.devices);
      add_generated(ref, policy, domain, role, {});
      break;
  }
  return ref;
}

bool wildcard(const std::string& s) { return s.find_first_of("*?[") != std::string::npos; }

std::string right_text(const Right& r) {
  return "'" + r.topic + "'" + (r.partition.empty() ? std::string() : " in partition '" + r.partition + "'");
}

// Topics only the bridge writes: a grant whose publish rights reach one of them is a bridge grant.
std::optional<std::string> bridge_topic_published(const ParsedGrant& g, const GrantPolicy& policy) {
  std::vector<std::string> bridge_only;
  std::vector<std::string> devices = policy.devices;
  devices.emplace_back("any_device");  // a pattern that covers a device not configured (yet)
  bridge_only.reserve(devices.size());
  for (const auto& d : devices) bridge_only.push_back(topic_name(policy.line, d, "status"));
  bridge_only.push_back(topic_name(policy.line, kBridgeNamespace, "diagnostics"));
  bridge_only.push_back(reply_topic(line_service_path(policy.line, "command")));
  for (const auto& r : g.publish) {
    for (const auto& t : bridge_only) {
      if (::fnmatch(r.topic.c_str(), t.c_str(), 0) == 0) return r.topic;
    }
  }
  return std::nullopt;
}

std::optional<Role> role_by_name(const ParsedGrant& g, const std::string& line) {
  const std::string prefix = line + "_";
  if (g.name.rfind(prefix, 0) != 0) return std::nullopt;
  return role_from_string(g.name.substr(prefix.size()));
}

bool within(const std::set<Right>& rights, const std::set<Right>& allowed) {
  return std::includes(allowed.begin(), allowed.end(), rights.begin(), rights.end());
}

void audit_grant(const ParsedGrant& g, const GrantPolicy& policy, std::uint32_t domain, GrantFindings& out) {
  const std::string who = "grant '" + g.name + "' for '" + g.subject + "'";
  if (g.default_allow) {
    out.errors.push_back(who + ": <default>ALLOW</default> allows every topic no rule names: pki.sh writes DENY");
  }
  const bool is_bridge = !policy.bridge_subject.empty() && g.subject == policy.bridge_subject;
  if (!is_bridge) {
    const auto named = role_by_name(g, policy.line);
    if (auto topic = bridge_topic_published(g, policy); topic || named == Role::bridge) {
      out.errors.push_back(
          who + " is a bridge grant (it may publish '" + (topic ? *topic : "what the bridge writes") +
          "', which only the bridge writes): only the bridge's own identity " +
          (policy.bridge_subject.empty() ? std::string("(not known here)") : "'" + policy.bridge_subject + "'") +
          " may hold one");
      return;
    }
  }
  std::optional<Role> role = is_bridge ? std::optional<Role>(Role::bridge) : role_by_name(g, policy.line);
  if (!role) {
    for (const Role r : {Role::observer, Role::operator_, Role::engineer}) {
      if (within(g.publish, reference(policy, domain, r).publish)) {
        role = r;
        break;
      }
    }
  }
  if (!role) role = Role::engineer;
  const Reference ref = reference(policy, domain, *role);
  const std::string as_role = "`linebridge-security permissions --role " + std::string(to_string(*role)) + "`";
  for (const auto& r : g.publish) {
    if (ref.publish.count(r) != 0) continue;
    out.errors.push_back(who + " (role " + std::string(to_string(*role)) + ") may publish " + right_text(r) + ": " +
                         (wildcard(r.topic) || wildcard(r.partition) ? "a wildcard " : "a right ") + as_role +
                         " does not give on line " + policy.line);
  }
  std::string extra;
  for (const auto& r : g.subscribe) {
    if (ref.subscribe.count(r) == 0) extra += (extra.empty() ? "" : ", ") + right_text(r);
  }
  if (!extra.empty()) {
    out.warnings.push_back(who + " (role " + std::string(to_string(*role)) + ") may read more than " + as_role +
                           " gives: " + extra);
  }
}

// OpenSSL objects owned by unique_ptr: F is the library's own free function.
template <auto F>
struct OpenSslFree {
  template <class T>
  void operator()(T* p) const {
    F(p);
  }
};

// The signed text of an S/MIME document, signature not checked (check_security_files does).
std::optional<std::string> smime_text(const std::string& path) {
  const auto read = read_bounded_file(path, "security file", ossl::kMaxSecurityFileBytes);
  if (!read) return std::nullopt;
  const std::string& bytes = *read;
  std::unique_ptr<BIO, OpenSslFree<BIO_free_all>> bio(BIO_new_mem_buf(bytes.data(), static_cast<int>(bytes.size())));
  BIO* content_raw = nullptr;
  std::unique_ptr<PKCS7, OpenSslFree<PKCS7_free>> p7(SMIME_read_PKCS7(bio.get(), &content_raw));
  std::unique_ptr<BIO, OpenSslFree<BIO_free_all>> content(content_raw);
  std::unique_ptr<X509_STORE, OpenSslFree<X509_STORE_free>> store(X509_STORE_new());
  std::unique_ptr<BIO, OpenSslFree<BIO_free_all>> out(BIO_new(BIO_s_mem()));
  const bool ok = p7 && PKCS7_verify(p7.get(), nullptr, store.get(), content.get(), out.get(),
                                     PKCS7_TEXT | PKCS7_NOVERIFY | PKCS7_NOSIGS) == 1;
  ERR_clear_error();
  if (!ok) return std::nullopt;
  BUF_MEM* mem = nullptr;
  BIO_get_mem_ptr(out.get(), &mem);
  return mem == nullptr ? std::string() : std::string(mem->data, mem->length);
}

}  // namespace

GrantFindings audit_grants(const std::string& permissions_xml, const GrantPolicy& policy, std::uint32_t domain) {
  GrantFindings out;
  auto grants = parse_grants(permissions_xml, domain);
  if (!grants) return out;  // malformed: the permissions check reports it
  for (const auto& g : *grants) audit_grant(g, policy, domain, out);
  return out;
}

std::vector<std::string> grant_warnings(const SecurityFiles& files, std::uint32_t domain) {
  if (!files.grant_policy) return {};
  auto text = smime_text(files.permissions);
  if (!text) return {};
  std::vector<std::string> out;
  for (auto& w : audit_grants(*text, *files.grant_policy, domain).warnings)
    out.push_back("permissions " + files.permissions + ": " + w);
  return out;
}

}  // namespace lb::ddsl
