#include "dds/grant_audit.hpp"

#include <fnmatch.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pkcs7.h>
#include <openssl/x509.h>
#include <tinyxml2.h>

#include <algorithm>
#include <cstring>
#include <ctime>
#include <iomanip>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include "base/bounded_file.hpp"
#include "dds/openssl_ptr.hpp"
#include "dds/participant.hpp"  // reply_topic
#include "dds/security_files.hpp"
#include "dds/security_policy.hpp"
#include "dds/topic_names.hpp"

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
  std::set<Right> relay;           // readers matched "relay only": the samples reach them, payloads encrypted
  std::vector<std::string> notes;  // what Fast DDS reads but ignores (warnings)
};

// ---------------------------------------------------------------------------------------------
// The permissions document as Fast DDS 2.9.1 reads it (PermissionsParser.cpp, CommonParser.cpp,
// Permissions.cpp of v2.9.1), step by step, so that what the audit judges is what Fast DDS
// enforces:
//  - every <topics> and every <partitions> of a <publish>, <subscribe> or <relay> counts, and
//    within one rule a topic of any of its <publish> elements may be written in a partition of
//    any of them (Fast DDS looks the topic up in all the rule's <publish> elements, then each of
//    the writer's partitions in all of them);
//  - a <publish> without <partitions> is the default partition ("");
//  - texts are taken as they are, blanks included (GetText, no trimming);
//  - a rule counts on a domain as Permissions.cpp's is_domain_in_set says: an <id_range> whose
//    <max> is missing or 0 is its <min> alone;
//  - what follows <default> is never read.
// A document the parser refuses is refused here with the reason: Fast DDS would give it nothing
// (its participant does not start, its peers do not authenticate it) and say only "Malformed
// permissions file", so nothing in it can be judged.

// Why Fast DDS refuses the document, with the line of the element.
struct Refusal {
  std::string why;
};
using Refused = std::optional<Refusal>;

Refusal refusal(const XMLElement* at, const std::string& why) {
  return {why + " (line " + std::to_string(at->GetLineNum()) + ")"};
}

bool named(const XMLElement* e, const char* name) { return std::strcmp(e->Name(), name) == 0; }

std::string element(const XMLElement* e) { return "<" + std::string(e->Name()) + ">"; }

// <domains>: <id>N</id> and <id_range><min>a</min><max>b</max></id_range>, as (first, second)
// pairs where second 0 means "first alone" (CommonParser.cpp parse_domain_id_set).
Refused read_domains(const XMLElement* domains, std::vector<std::pair<std::uint32_t, std::uint32_t>>& out) {
  const XMLElement* e = domains->FirstChildElement();
  if (e == nullptr) return refusal(domains, "<domains> without an <id> or <id_range>");
  for (; e != nullptr; e = e->NextSiblingElement()) {
    if (named(e, "id")) {
      std::uint32_t id = 0;
      if (e->QueryUnsignedText(&id) != tinyxml2::XML_SUCCESS) return refusal(e, "<id> is not a domain number");
      out.emplace_back(id, 0);
    } else if (named(e, "id_range")) {
      const XMLElement* sub = e->FirstChildElement();
      std::uint32_t lo = 0;
      std::uint32_t hi = 0;
      if (sub == nullptr) return refusal(e, "<id_range> without <min> or <max>");
      if (named(sub, "min")) {
        if (sub->QueryUnsignedText(&lo) != tinyxml2::XML_SUCCESS) return refusal(sub, "<min> is not a domain number");
        const XMLElement* next = sub->NextSiblingElement();
        if (next != nullptr && named(next, "max") && next->QueryUnsignedText(&hi) != tinyxml2::XML_SUCCESS) {
          return refusal(next, "<max> is not a domain number");
        }
      } else if (named(sub, "max")) {
        if (sub->QueryUnsignedText(&hi) != tinyxml2::XML_SUCCESS) return refusal(sub, "<max> is not a domain number");
      } else {
        return refusal(sub, element(sub) + " in <id_range>: Fast DDS takes <min> and <max>");
      }
      out.emplace_back(lo, hi);
    } else {
      return refusal(e, element(e) + " in <domains>: Fast DDS takes <id> and <id_range>");
    }
  }
  return std::nullopt;
}

bool ranges_cover(const std::vector<std::pair<std::uint32_t, std::uint32_t>>& ranges, std::uint32_t domain) {
  return std::any_of(ranges.begin(), ranges.end(), [domain](const auto& r) {
    return r.second == 0 ? domain == r.first : domain >= r.first && domain <= r.second;
  });
}

// The topics and partitions of a <publish>, <subscribe> or <relay> (parse_criteria).
struct Criteria {
  std::vector<std::string> topics;
  std::vector<std::string> partitions;
};

Refused read_list(const XMLElement* list, const char* item, bool empty_allowed, std::vector<std::string>& out) {
  const XMLElement* e = list->FirstChildElement();
  if (e == nullptr) return refusal(list, element(list) + " without a <" + item + ">");
  for (; e != nullptr; e = e->NextSiblingElement()) {
    if (!named(e, item))
      return refusal(e, element(e) + " in " + element(list) + ": Fast DDS takes <" + item + "> only");
    if (e->GetText() != nullptr) {
      out.emplace_back(e->GetText());
    } else if (empty_allowed && e->NoChildren()) {
      out.emplace_back();  // <partition/>: the default partition
    } else {
      return refusal(e, "<" + std::string(item) + "> without a name");
    }
  }
  return std::nullopt;
}

Refused read_criteria(const XMLElement* block, Criteria& c, std::vector<std::string>& notes) {
  for (const XMLElement* e = block->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
    if (named(e, "topics")) {
      if (auto r = read_list(e, "topic", false, c.topics)) return r;
    } else if (named(e, "partitions")) {
      if (auto r = read_list(e, "partition", true, c.partitions)) return r;
    } else if (named(e, "data_tags")) {
      notes.push_back("<data_tags> (line " + std::to_string(e->GetLineNum()) +
                      ") is not enforced by Fast DDS 2.9.1: the rule is not limited to those tags");
    } else {
      return refusal(e,
                     element(e) + " in " + element(block) + ": Fast DDS takes <topics>, <partitions> and <data_tags>");
    }
  }
  if (c.partitions.empty()) c.partitions.emplace_back();
  return std::nullopt;
}

// Every topic of the rule's blocks of one kind with every partition of them.
void add_rights(const std::vector<Criteria>& blocks, std::set<Right>& rights) {
  std::set<std::string> topics;
  std::set<std::string> partitions;
  for (const auto& c : blocks) {
    topics.insert(c.topics.begin(), c.topics.end());
    partitions.insert(c.partitions.begin(), c.partitions.end());
  }
  for (const auto& t : topics) {
    for (const auto& p : partitions) rights.insert({t, p});
  }
}

// An <allow_rule> or <deny_rule> (parse_rule). Deny rules only take rights away, and only where
// they come first: what a grant may at most do is judged from the allow rules.
Refused read_rule(const XMLElement* rule, std::uint32_t domain, ParsedGrant& grant) {
  const XMLElement* domains = rule->FirstChildElement();
  if (domains == nullptr || !named(domains, "domains")) {
    return refusal(domains ? domains : rule, element(rule) + " must begin with <domains>");
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> ranges;
  if (auto r = read_domains(domains, ranges)) return r;
  std::vector<Criteria> publish;
  std::vector<Criteria> subscribe;
  std::vector<Criteria> relay;
  for (const XMLElement* e = domains->NextSiblingElement(); e != nullptr; e = e->NextSiblingElement()) {
    std::vector<Criteria>* blocks = named(e, "publish")     ? &publish
                                    : named(e, "subscribe") ? &subscribe
                                    : named(e, "relay")     ? &relay
                                                            : nullptr;
    if (blocks == nullptr) {
      return refusal(e, element(e) + " in " + element(rule) + ": Fast DDS takes <publish>, <subscribe> and <relay>");
    }
    if (auto r = read_criteria(e, blocks->emplace_back(), grant.notes)) return r;
  }
  if (named(rule, "allow_rule") && ranges_cover(ranges, domain)) {
    add_rights(publish, grant.publish);
    add_rights(subscribe, grant.subscribe);
    add_rights(relay, grant.relay);
  }
  return std::nullopt;
}

// Fast DDS reads grant times with std::get_time "%Y-%m-%dT%T" (parse_validity).
bool readable_time(const XMLElement* e) {
  if (e == nullptr || e->GetText() == nullptr) return false;
  std::tm time{};
  std::istringstream stream(e->GetText());
  stream >> std::get_time(&time, "%Y-%m-%dT%T");
  return !stream.fail();
}

Refused read_validity(const XMLElement* validity) {
  const XMLElement* nb = validity->FirstChildElement();
  if (nb == nullptr || !named(nb, "not_before"))
    return refusal(nb ? nb : validity, "<validity> must begin with <not_before>");
  if (!readable_time(nb)) return refusal(nb, "<not_before> is not a time as YYYY-MM-DDThh:mm:ss");
  const XMLElement* na = nb->NextSiblingElement();
  if (na == nullptr || !named(na, "not_after"))
    return refusal(na ? na : nb, "<not_before> must be followed by <not_after>");
  if (!readable_time(na)) return refusal(na, "<not_after> is not a time as YYYY-MM-DDThh:mm:ss");
  return std::nullopt;
}

// <grant name=...>: <subject_name>, <validity>, rules, <default> (parse_grant).
Refused read_grant(const XMLElement* g, std::uint32_t domain, ParsedGrant& grant) {
  if (g->Attribute("name") == nullptr) return refusal(g, "a <grant> without a name attribute");
  grant.name = g->Attribute("name");
  const XMLElement* subject = g->FirstChildElement();
  if (subject == nullptr || !named(subject, "subject_name")) {
    return refusal(subject ? subject : g, "<grant> must begin with <subject_name>");
  }
  if (subject->GetText() == nullptr) return refusal(subject, "<subject_name> without a name");
  grant.subject = subject->GetText();
  const XMLElement* validity = subject->NextSiblingElement();
  if (validity == nullptr || !named(validity, "validity")) {
    return refusal(validity ? validity : subject, "<subject_name> must be followed by <validity>");
  }
  if (auto r = read_validity(validity)) return r;
  const XMLElement* e = validity->NextSiblingElement();
  if (e == nullptr) return refusal(validity, "<validity> must be followed by <allow_rule>, <deny_rule> or <default>");
  for (; e != nullptr && (named(e, "allow_rule") || named(e, "deny_rule")); e = e->NextSiblingElement()) {
    if (auto r = read_rule(e, domain, grant)) return r;
  }
  if (e == nullptr || !named(e, "default")) {
    return refusal(e ? e : g, (e ? element(e) : std::string("the end of the grant")) +
                                  " where <default> must be (after the rules)");
  }
  if (e->GetText() == nullptr || (std::strcmp(e->GetText(), "ALLOW") != 0 && std::strcmp(e->GetText(), "DENY") != 0)) {
    return refusal(e, "<default> must be ALLOW or DENY");
  }
  grant.default_allow = std::strcmp(e->GetText(), "ALLOW") == 0;
  for (const XMLElement* rest = e->NextSiblingElement(); rest != nullptr; rest = rest->NextSiblingElement()) {
    grant.notes.push_back(element(rest) + " after <default> (line " + std::to_string(rest->GetLineNum()) +
                          ") is never read by Fast DDS 2.9.1: it grants nothing");
  }
  return std::nullopt;
}

struct ParsedDocument {
  std::vector<ParsedGrant> grants;
  std::optional<Refusal> refused;
};

// nullopt: not XML, or no <dds><permissions> (check_permissions reports that itself).
std::optional<ParsedDocument> parse_grants(const std::string& xml, std::uint32_t domain) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) return std::nullopt;
  const XMLElement* root = doc.RootElement();
  ParsedDocument out;
  if (root != nullptr && !named(root, "dds") && doc.FirstChildElement("dds") != nullptr) {
    out.refused = refusal(root, element(root) + " where <dds> must be (the document's first element)");
    return out;
  }
  const XMLElement* perms = root && named(root, "dds") ? root->FirstChildElement("permissions") : nullptr;
  if (perms == nullptr) return std::nullopt;
  if (root->FirstChildElement() != perms) {
    out.refused = refusal(root->FirstChildElement(), element(root->FirstChildElement()) +
                                                         " where <permissions> must be (the first element in <dds>)");
    return out;
  }
  const XMLElement* g = perms->FirstChildElement();
  if (g == nullptr) out.refused = refusal(perms, "<permissions> without a <grant>");
  for (; g != nullptr && !out.refused; g = g->NextSiblingElement()) {
    if (!named(g, "grant")) {
      out.refused = refusal(g, element(g) + " in <permissions>: Fast DDS takes <grant> only");
    } else {
      out.refused = read_grant(g, domain, out.grants.emplace_back());
    }
  }
  return out;
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
  if (!parsed || parsed->refused || parsed->grants.empty()) return;
  const ParsedGrant& generated = parsed->grants.front();
  ref.publish.insert(generated.publish.begin(), generated.publish.end());
  ref.subscribe.insert(generated.subscribe.begin(), generated.subscribe.end());
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
      if (::fnmatch(r.topic.c_str(), t.c_str(), FNM_NOESCAPE) == 0) return r.topic;  // as Fast DDS matches
    }
  }
  return std::nullopt;
}

std::optional<Role> role_by_name(const ParsedGrant& g, const std::string& line) {
  const std::string prefix = line + "_";
  if (g.name.rfind(prefix, 0) != 0) return std::nullopt;
  return role_from_string(g.name.substr(prefix.size()));
}

// Subjects compared as Fast DDS compares a grant's with a certificate's (rfc2253_string_compare):
// part by part between commas, blanks around each part ignored.
std::vector<std::string> subject_parts(const std::string& subject) {
  std::vector<std::string> out;
  std::istringstream in(subject);
  for (std::string part; std::getline(in, part, ',');) {
    const auto lo = part.find_first_not_of(' ');
    out.push_back(lo == std::string::npos ? std::string() : part.substr(lo, part.find_last_not_of(' ') - lo + 1));
  }
  return out;
}

bool same_subject(const std::string& a, const std::string& b) { return subject_parts(a) == subject_parts(b); }

bool within(const std::set<Right>& rights, const std::set<Right>& allowed) {
  return std::includes(allowed.begin(), allowed.end(), rights.begin(), rights.end());
}

void audit_grant(const ParsedGrant& g, const GrantPolicy& policy, std::uint32_t domain, GrantFindings& out) {
  const std::string who = "grant '" + g.name + "' for '" + g.subject + "'";
  if (g.default_allow) {
    out.errors.push_back(who + ": <default>ALLOW</default> allows every topic no rule names: pki.sh writes DENY");
  }
  for (const auto& n : g.notes) out.warnings.push_back(who + ": " + n);
  const bool is_bridge = !policy.bridge_subject.empty() && same_subject(g.subject, policy.bridge_subject);
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
  for (const auto& r : g.relay) {  // matched, given the samples but not the payload key: at most a read
    if (ref.subscribe.count(r) == 0) extra += (extra.empty() ? "" : ", ") + right_text(r) + " (<relay>)";
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
  auto parsed = parse_grants(permissions_xml, domain);
  if (!parsed) return out;  // malformed: the permissions check reports it
  if (parsed->refused) {
    out.errors.push_back(
        "Fast DDS 2.9.1 refuses this permissions document (\"Malformed permissions file\"): " + parsed->refused->why +
        "; a participant with it does not start and its peers do not authenticate it");
    return out;
  }
  for (const auto& g : parsed->grants) audit_grant(g, policy, domain, out);
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
