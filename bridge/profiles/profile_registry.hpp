#pragma once
// The profiles a line can use: the built-in ones (compiled in from config/profiles/) plus any
// loaded from files. Looked up by id and version, e.g. ("cia420-4", "3.1").

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "base/result.hpp"
#include "profiles/profile.hpp"

namespace lb::profiles {

// Parses one profile definition; `source` names it in error messages.
Result<Profile> parse_profile(const std::string& yaml_text, const std::string& source);
// Reads and parses one profile file; errors name the file (and line and column).
Result<Profile> load_profile_file(const std::string& path);

class ProfileRegistry {
 public:
  // The built-in profiles; throws on a broken built-in (a build defect, not a user error).
  static ProfileRegistry builtin();

  Result<void> add_file(const std::string& path);
  void add(Profile profile);

  const Profile* find(std::string_view id, std::string_view version) const;
  std::span<const Profile> profiles() const { return profiles_; }
  std::vector<std::string> keys() const;  // "id@version" of every profile, for error messages

 private:
  std::vector<Profile> profiles_;
};

}  // namespace lb::profiles
