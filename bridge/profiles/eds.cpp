#include "profiles/eds.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <fstream>
#include <sstream>

#include "profiles/config_file.hpp"

namespace lb::profiles {
namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front())) != 0) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back())) != 0) s.remove_suffix(1);
  return s;
}

// CiA 306 data type codes linebridge's objects use.
std::optional<canopen::DataType> data_type(std::uint16_t code) {
  using canopen::DataType;
  switch (code) {
    case 0x0001: return DataType::boolean;
    case 0x0002: return DataType::integer8;
    case 0x0003: return DataType::integer16;
    case 0x0004: return DataType::integer32;
    case 0x0005: return DataType::unsigned8;
    case 0x0006: return DataType::unsigned16;
    case 0x0007: return DataType::unsigned32;
    case 0x0008: return DataType::real32;
    case 0x0009: return DataType::visible_string;
    case 0x000A: return DataType::octet_string;
    case 0x0011: return DataType::real64;
    case 0x0015: return DataType::integer64;
    case 0x001B: return DataType::unsigned64;
    default: return std::nullopt;
  }
}

Result<std::uint64_t> plain_number(std::string_view t) {
  int base = 10;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) {
    base = 16;
    t.remove_prefix(2);
  } else if (t.size() > 1 && t[0] == '0') {
    base = 8;
    t.remove_prefix(1);
  }
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v, base);
  if (ec != std::errc() || end != t.data() + t.size() || t.empty()) return make_error("not a number");
  return v;
}

// "[1018sub2]" -> 1018h sub 2; "[1018]" -> 1018h, no sub; anything else -> nullopt.
struct ObjectSection {
  std::uint16_t index = 0;
  bool has_sub = false;
  std::uint8_t sub = 0;
};

std::optional<ObjectSection> object_section(std::string_view name) {
  const auto l = lower(name);
  const auto sub_at = l.find("sub");
  const std::string index_text = l.substr(0, sub_at);
  if (index_text.size() != 4) return std::nullopt;
  unsigned index = 0;
  if (std::from_chars(index_text.data(), index_text.data() + 4, index, 16).ptr != index_text.data() + 4)
    return std::nullopt;
  ObjectSection out;
  out.index = static_cast<std::uint16_t>(index);
  if (sub_at == std::string::npos) return out;
  const std::string sub_text = l.substr(sub_at + 3);
  unsigned sub = 0;
  const auto [end, ec] = std::from_chars(sub_text.data(), sub_text.data() + sub_text.size(), sub, 16);
  if (ec != std::errc() || end != sub_text.data() + sub_text.size() || sub > 255) return std::nullopt;
  out.has_sub = true;
  out.sub = static_cast<std::uint8_t>(sub);
  return out;
}

struct Section {
  std::string name;
  int line = 0;
  std::map<std::string, std::string> keys;  // lower-case key -> value
};

}  // namespace

Result<std::uint64_t> eds_number(std::string_view text, std::optional<std::uint8_t> node_id) {
  const std::string t = lower(trim(text));
  const auto at = t.find("$nodeid");
  if (at == std::string::npos) {
    auto v = plain_number(t);
    if (!v) return make_error("'" + std::string(text) + "' is not a number");
    return v;
  }
  if (!node_id) return make_error("'" + std::string(text) + "' needs a node-ID ($NODEID): give --node-id or use a DCF");
  std::string rest = t.substr(0, at) + t.substr(at + 7);  // "+0x180" or "0x180+"
  std::erase_if(rest, [](char c) { return c == '+' || std::isspace(static_cast<unsigned char>(c)) != 0; });
  std::uint64_t offset = 0;
  if (!rest.empty()) {
    auto v = plain_number(rest);
    if (!v) return make_error("'" + std::string(text) + "' is not a number");
    offset = *v;
  }
  return offset + *node_id;
}

const EdsEntry* EdsFile::find(std::uint16_t index, std::uint8_t sub) const {
  for (const auto& e : entries) {
    if (e.index == index && e.sub == sub) return &e;
  }
  return nullptr;
}

Result<std::optional<std::uint64_t>> EdsFile::value(std::uint16_t index, std::uint8_t sub,
                                                    std::optional<std::uint8_t> node) const {
  const auto* e = find(index, sub);
  if (e == nullptr) return std::optional<std::uint64_t>{};
  const auto& text = !e->parameter_value.empty() ? e->parameter_value : e->default_value;
  if (trim(text).empty()) return std::optional<std::uint64_t>{};
  auto v = eds_number(text, node);
  if (!v) return make_error(e->where + ": " + e->name + ": " + v.error().message);
  return std::optional<std::uint64_t>(*v);
}

Result<EdsFile> parse_eds(const std::string& text, const std::string& source) {
  std::vector<Section> sections;
  std::istringstream in(text);
  std::string raw;
  for (int line = 1; std::getline(in, raw); ++line) {
    std::string_view l = trim(raw);
    if (l.empty() || l.front() == ';' || l.front() == '#') continue;
    if (l.front() == '[') {
      if (l.back() != ']') return make_error(source + ":" + std::to_string(line) + ": a section header ends with ']'");
      sections.push_back({std::string(trim(l.substr(1, l.size() - 2))), line, {}});
      continue;
    }
    const auto eq = l.find('=');
    if (eq == std::string_view::npos) return make_error(source + ":" + std::to_string(line) + ": expected key=value");
    if (sections.empty()) return make_error(source + ":" + std::to_string(line) + ": key=value before any [section]");
    auto value = trim(l.substr(eq + 1));
    if (const auto comment = value.find(';'); comment != std::string_view::npos) value = trim(value.substr(0, comment));
    sections.back().keys[lower(trim(l.substr(0, eq)))] = std::string(value);
  }

  EdsFile eds;
  eds.source = source;
  const auto key = [](const Section& s, const char* k) {
    auto it = s.keys.find(k);
    return it == s.keys.end() ? std::string() : it->second;
  };
  const auto number = [&](const Section& s, const char* k) -> Result<std::optional<std::uint32_t>> {
    const auto t = key(s, k);
    if (t.empty()) return std::optional<std::uint32_t>{};
    auto v = eds_number(t, std::nullopt);
    if (!v || *v > 0xFFFF'FFFFULL)
      return make_error(source + ":" + std::to_string(s.line) + ": [" + s.name + "] " + k + " '" + t +
                        "' is not a 32-bit number");
    return std::optional<std::uint32_t>(static_cast<std::uint32_t>(*v));
  };
  bool device_info = false;
  for (const auto& s : sections) {
    const auto name = lower(s.name);
    if (name == "deviceinfo") {
      device_info = true;
      eds.vendor_name = key(s, "vendorname");
      eds.product_name = key(s, "productname");
      auto v = number(s, "vendornumber");
      auto p = number(s, "productnumber");
      auto r = number(s, "revisionnumber");
      if (!v) return v.error();
      if (!p) return p.error();
      if (!r) return r.error();
      eds.vendor_number = *v;
      eds.product_number = *p;
      eds.revision_number = *r;
      continue;
    }
    if (name == "devicecomissioning" || name == "devicecommissioning") {
      auto n = number(s, "nodeid");
      if (!n) return n.error();
      if (*n && (**n < 1 || **n > 127))
        return make_error(source + ":" + std::to_string(s.line) + ": NodeID must be 1..127");
      if (*n) eds.node_id = static_cast<std::uint8_t>(**n);
      continue;
    }
    const auto obj = object_section(s.name);
    if (!obj) continue;  // FileInfo, MandatoryObjects, comments, ...
    const auto object_type = key(s, "objecttype");
    const auto type = object_type.empty() ? Result<std::uint64_t>(7) : eds_number(object_type, std::nullopt);
    const bool var = !type || *type == 7;
    if (!obj->has_sub && !var) continue;  // a RECORD or ARRAY header: its subs are sections of their own
    EdsEntry e;
    e.index = obj->index;
    e.sub = obj->sub;
    e.name = key(s, "parametername");
    const auto type_text = key(s, "datatype");
    if (!type_text.empty()) {
      auto code = eds_number(type_text, std::nullopt);
      if (!code || *code > 0xFFFF)
        return make_error(source + ":" + std::to_string(s.line) + ": [" + s.name + "] DataType '" + type_text +
                          "' is not a type code");
      e.type_code = static_cast<std::uint16_t>(*code);
      e.type = data_type(e.type_code);
    }
    e.access = lower(key(s, "accesstype"));
    e.default_value = key(s, "defaultvalue");
    e.parameter_value = key(s, "parametervalue");
    e.pdo_mapping = key(s, "pdomapping") == "1";
    e.where = source + ":" + std::to_string(s.line);
    eds.entries.push_back(std::move(e));
  }
  if (!device_info) return make_error(source + ": no [DeviceInfo] section: not an EDS or DCF file (CiA 306)");
  return eds;
}

// Bounded like a line file: /dev/zero, a FIFO or a huge file is refused, not read until memory runs out.
Result<EdsFile> load_eds(const std::string& path) {
  auto text = read_config_file(path, "EDS/DCF file");
  if (!text) return text.error();
  return parse_eds(*text, path);
}

}  // namespace lb::profiles
