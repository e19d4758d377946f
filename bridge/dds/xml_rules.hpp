#pragma once
// Reading DDS Security XML (governance, permissions) as Fast DDS's parsers do: element text
// without surrounding blanks, and whether a <domains> list covers a domain.

#include <tinyxml2.h>

#include <cstdint>
#include <string>

namespace lb::ddsl::xml {

inline std::string trimmed_text(const tinyxml2::XMLElement* e) {
  std::string s = e != nullptr && e->GetText() != nullptr ? e->GetText() : "";
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

// <domains><id>N</id><id_range><min>a</min><max>b</max></id_range></domains>
inline bool covers(const tinyxml2::XMLElement* domains, std::uint32_t domain) {
  for (const auto* e = domains ? domains->FirstChildElement() : nullptr; e != nullptr; e = e->NextSiblingElement()) {
    const std::string name = e->Name();
    if (name == "id" && e->UnsignedText(0xffffffffU) == domain) return true;
    if (name == "id_range") {
      const auto* lo = e->FirstChildElement("min");
      const auto* hi = e->FirstChildElement("max");
      if (domain >= (lo ? lo->UnsignedText(0) : 0U) && domain <= (hi ? hi->UnsignedText(0xffffffffU) : 0xffffffffU))
        return true;
    }
  }
  return false;
}

}  // namespace lb::ddsl::xml
