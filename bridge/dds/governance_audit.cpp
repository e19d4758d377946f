#include "dds/governance_audit.hpp"

#include <tinyxml2.h>

#include "dds/xml_rules.hpp"

namespace lb::ddsl {
namespace {

using tinyxml2::XMLElement;

using xml::covers;
using xml::trimmed_text;

// "ENCRYPT" or "ENCRYPT_WITH_ORIGIN_AUTHENTICATION"; anything else (NONE, SIGN..., missing, which
// Fast DDS reads as NONE) is a problem.
void require_encrypt(const XMLElement* parent, const char* element, const std::string& where, const char* why,
                     std::vector<std::string>& problems) {
  const std::string kind = trimmed_text(parent->FirstChildElement(element));
  if (kind.rfind("ENCRYPT", 0) == 0) return;
  problems.push_back(where + ": " + element + " " + (kind.empty() ? std::string("(missing: NONE)") : kind) + " " + why +
                     ": use ENCRYPT");
}

void require_true(const XMLElement* parent, const char* element, const std::string& where, const char* why,
                  std::vector<std::string>& problems) {
  bool v = false;
  if (const XMLElement* e = parent->FirstChildElement(element)) e->QueryBoolText(&v);
  if (!v) problems.push_back(where + ": " + element + " is not true: " + why);
}

}  // namespace

std::vector<std::string> governance_protection_problems(const std::string& xml, std::uint32_t domain) {
  std::vector<std::string> problems;
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) return problems;
  const XMLElement* dds = doc.FirstChildElement("dds");
  const XMLElement* rules = dds ? dds->FirstChildElement("domain_access_rules") : nullptr;
  const XMLElement* rule = rules ? rules->FirstChildElement("domain_rule") : nullptr;
  while (rule != nullptr && !covers(rule->FirstChildElement("domains"), domain))
    rule = rule->NextSiblingElement("domain_rule");
  if (rule == nullptr) return problems;

  const std::string where = "the domain_rule of domain " + std::to_string(domain);
  require_encrypt(rule, "discovery_protection_kind", where,
                  "sends the device, topic, type and partition names of every endpoint readable on the wire", problems);
  require_encrypt(rule, "liveliness_protection_kind", where,
                  "leaves liveliness readable and forgeable (a forged message keeps a dead writer alive)", problems);
  const XMLElement* topics = rule->FirstChildElement("topic_access_rules");
  for (const XMLElement* t = topics ? topics->FirstChildElement("topic_rule") : nullptr; t != nullptr;
       t = t->NextSiblingElement("topic_rule")) {
    const std::string topic = "topic_rule '" + trimmed_text(t->FirstChildElement("topic_expression")) + "'";
    require_true(t, "enable_discovery_protection", topic,
                 "its endpoints are announced on the unprotected discovery endpoints, topic and type names in clear",
                 problems);
    require_true(t, "enable_liveliness_protection", topic,
                 "its writers' liveliness goes on the unprotected liveliness endpoint", problems);
    require_encrypt(t, "metadata_protection_kind", topic,
                    "leaves its submessages (heartbeats, gaps, acknowledgements, writer GUIDs) readable and forgeable",
                    problems);
  }
  return problems;
}

}  // namespace lb::ddsl
