#pragma once
// What a check of one security file found: problems refuse the start (the bridge exits 2),
// warnings are logged and printed by the pre-flight checks. Each names its key and file.

#include <string>
#include <vector>

namespace lb::ddsl {

struct FileFinding {
  std::string key;   // the dds.security key, e.g. "identity_crl"
  std::string path;  // the file
  std::string why;
  std::string text() const { return key + " " + path + ": " + why; }
};

struct FileFindings {
  std::vector<FileFinding> problems;
  std::vector<FileFinding> warnings;
};

}  // namespace lb::ddsl
