#pragma once
// A file's whole text, for unit tests that check what the code under test wrote ("" if absent).
#include <fstream>
#include <iterator>
#include <string>

namespace lb::test {

inline std::string file_text(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace lb::test
