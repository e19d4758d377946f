#include "dds/site_profiles.hpp"

#include <tinyxml2.h>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include "base/bounded_file.hpp"

namespace lb::ddsl {
namespace {

namespace fdds = eprosima::fastdds::dds;

// <dds><profiles>...</profiles></dds> or <profiles>...</profiles>, as Fast DDS accepts both.
const tinyxml2::XMLElement* profiles_of(const tinyxml2::XMLDocument& doc) {
  const auto* root = doc.RootElement();
  if (root == nullptr) return nullptr;
  if (std::strcmp(root->Name(), "profiles") == 0) return root;
  return root->FirstChildElement("profiles");
}

Result<void> read_names(const std::string& path, SiteProfiles& out) {
  // Bounded, and a regular file only, before Fast DDS is given the path (a FIFO would block it).
  const auto text = read_bounded_file(path, "DDS profiles file");
  if (!text) return make_error(text.error().message);
  tinyxml2::XMLDocument doc;
  if (doc.Parse(text->data(), text->size()) != tinyxml2::XML_SUCCESS) {
    return make_error(path + ":" + std::to_string(doc.ErrorLineNum()) + ": XML error: " + doc.ErrorStr());
  }
  const auto* profiles = profiles_of(doc);
  if (profiles == nullptr) return make_error(path + ": not a Fast DDS profiles file (no <profiles> element)");
  for (const auto* e = profiles->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
    const char* name = e->Attribute("profile_name");
    if (name == nullptr) continue;
    const std::string kind = e->Name();
    const bool is_default = e->BoolAttribute("is_default_profile", false);
    if (kind == "participant") {
      out.participants.emplace_back(name);
      if (is_default) out.default_participant = name;
    } else if (kind == "data_writer" || kind == "publisher") {
      out.writers.emplace_back(name);
    } else if (kind == "data_reader" || kind == "subscriber") {
      out.readers.emplace_back(name);
    }
  }
  return {};
}

}  // namespace

bool SiteProfiles::has(const std::vector<std::string>& names, const std::string& name) const {
  return std::find(names.begin(), names.end(), name) != names.end();
}

Result<SiteProfiles> load_site_profiles(const std::string& profiles_file) {
  SiteProfiles site;
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  // The standard variable: Fast DDS loads it (and DEFAULT_FASTRTPS_PROFILES.xml in the working
  // directory) by itself; read here too, so its errors and profile names are ours to report.
  if (const char* env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE"); env != nullptr && *env != '\0') {
    if (auto r = read_names(env, site); !r) return make_error("FASTRTPS_DEFAULT_PROFILES_FILE: " + r.error().message);
    site.files.emplace_back(env);
  }
  factory->load_profiles();
  if (!profiles_file.empty()) {
    site.default_participant.reset();  // only the line file's own default counts over the environment's
    if (auto r = read_names(profiles_file, site); !r) return r.error();
    if (factory->load_XML_profiles_file(profiles_file) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      return make_error(profiles_file + ": Fast DDS refused the profiles file (its messages above say why)");
    }
    site.files.push_back(profiles_file);
  }
  return site;
}

}  // namespace lb::ddsl
