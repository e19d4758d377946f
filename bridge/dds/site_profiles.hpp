#pragma once
// A site's Fast DDS XML profiles files: FASTRTPS_DEFAULT_PROFILES_FILE (Fast DDS loads it by
// itself) and the line file's dds.profiles_file. Read once with tinyxml2 for what Fast DDS does not
// say (which profiles exist, syntax errors with their line), then loaded into Fast DDS.

#include <optional>
#include <string>
#include <vector>

#include "base/result.hpp"

namespace lb::ddsl {

struct SiteProfiles {
  std::vector<std::string> files;                  // in loading order
  std::vector<std::string> participants;           // participant profile names
  std::optional<std::string> default_participant;  // the last file's is_default_profile="true" one
  std::vector<std::string> writers;                // data_writer (publisher) profile names
  std::vector<std::string> readers;                // data_reader (subscriber) profile names
  bool has(const std::vector<std::string>& names, const std::string& name) const;
};

// Reads and loads FASTRTPS_DEFAULT_PROFILES_FILE (when set) and `profiles_file` (when not empty).
// Errors name the file and, for XML syntax, the line. Loading twice is harmless.
Result<SiteProfiles> load_site_profiles(const std::string& profiles_file);

}  // namespace lb::ddsl
