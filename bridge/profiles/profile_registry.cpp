#include "profiles/profile_registry.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "profiles/builtin_profiles.hpp"
#include "profiles/yaml_source.hpp"

namespace lb::profiles {
namespace {

Access parse_access(const YamlSource& src, const YAML::Node& node) {
  const auto text = src.as<std::string>(node, "access");
  if (text == "ro") return Access::ro;
  if (text == "wo") return Access::wo;
  if (text == "rw") return Access::rw;
  if (text == "const") return Access::const_;
  src.fail(node, "access must be ro, wo, rw or const, not '" + text + "'");
}

template <class T>
T in_range(const YamlSource& src, const YAML::Node& map, std::string_view key, std::int64_t lo, std::int64_t hi) {
  const auto v = src.required<std::int64_t>(map, key, "entry");
  if (v < lo || v > hi) {
    src.fail(map[std::string(key)], std::string(key) + " " + std::to_string(v) + " is outside " +
                                        std::to_string(lo) + ".." + std::to_string(hi));
  }
  return static_cast<T>(v);
}

void parse_objects(const YamlSource& src, const YAML::Node& list, Profile& p) {
  src.expect_sequence(list, "objects");
  for (const auto& o : list) {
    src.check_keys(o, "object",
                   {"index", "sub", "name", "type", "access", "unit", "scale", "eng_unit", "min", "max", "array",
                    "mandatory"});
    ObjectDef def;
    def.index = in_range<std::uint16_t>(src, o, "index", 0x1000, 0xFFFF);
    def.sub = static_cast<std::uint8_t>(src.optional<int>(o, "sub").value_or(0));
    def.name = src.required<std::string>(o, "name", "object");
    const auto type_text = src.required<std::string>(o, "type", "object");
    const auto type = canopen::parse_data_type(type_text);
    if (!type) src.fail(o["type"], "unknown data type '" + type_text + "'");
    def.type = *type;
    def.access = parse_access(src, o["access"]);
    def.unit = src.optional<std::string>(o, "unit").value_or("");
    def.scale = src.optional<double>(o, "scale").value_or(1.0);
    if (def.scale == 0.0) src.fail(o["scale"], "scale must not be 0");
    def.eng_unit = src.optional<std::string>(o, "eng_unit").value_or(def.unit);
    def.min = src.optional<std::int64_t>(o, "min");
    def.max = src.optional<std::int64_t>(o, "max");
    def.mandatory = src.optional<bool>(o, "mandatory").value_or(true);
    if (p.object(def.name) != nullptr) src.fail(o["name"], "duplicate object name '" + def.name + "'");
    if (const auto n = src.optional<int>(o, "array")) {
      // ARRAY objects: sub 0 holds the highest sub-index, subs 1..n the elements.
      if (*n < 1 || *n > 254) src.fail(o["array"], "array size must be 1..254");
      ObjectDef count{def.index, 0, def.name + "_count", canopen::DataType::unsigned8, Access::const_, "", 1.0, "", {}, {}, def.mandatory};
      p.objects.push_back(count);
      for (int i = 1; i <= *n; ++i) {
        ObjectDef element = def;
        element.sub = static_cast<std::uint8_t>(i);
        element.name = def.name + "_" + std::to_string(i);
        p.objects.push_back(element);
      }
    } else {
      p.objects.push_back(def);
    }
  }
}

void parse_bitsets(const YamlSource& src, const YAML::Node& map, Profile& p) {
  src.expect_map(map, "bitsets");
  for (const auto& kv : map) {
    BitSet set;
    set.name = kv.first.as<std::string>();
    src.check_keys(kv.second, "bitset " + set.name, {"object", "bits"});
    set.index = in_range<std::uint16_t>(src, kv.second, "object", 0x1000, 0xFFFF);
    const ObjectDef* obj = p.object(set.index);
    if (obj == nullptr) src.fail(kv.second["object"], "bitset " + set.name + " names an object the profile does not define");
    const unsigned width = canopen::bit_size(obj->type);
    const YAML::Node bits = kv.second["bits"];
    src.expect_map(bits, "bits");
    for (const auto& b : bits) {
      BitField field{b.first.as<std::string>(), src.as<unsigned>(b.second, b.first.as<std::string>())};
      if (field.bit >= width) {
        src.fail(b.second, "bit " + std::to_string(field.bit) + " does not exist in a " + std::to_string(width) + "-bit word");
      }
      for (const auto& other : set.bits) {
        if (other.bit == field.bit) src.fail(b.second, "bit " + std::to_string(field.bit) + " is already " + other.name);
        if (other.name == field.name) src.fail(b.first, "duplicate bit name '" + field.name + "'");
      }
      set.bits.push_back(field);
    }
    p.bitsets.push_back(std::move(set));
  }
}

void parse_pdos(const YamlSource& src, const YAML::Node& list, Profile& p) {
  src.expect_sequence(list, "pdos");
  for (const auto& n : list) {
    src.check_keys(n, "pdo", {"name", "direction", "cob_id", "transmission_type", "mapping"});
    PdoDef pdo;
    pdo.name = src.required<std::string>(n, "name", "pdo");
    const auto dir = src.required<std::string>(n, "direction", "pdo");
    if (dir != "tx" && dir != "rx") src.fail(n["direction"], "direction must be tx (device sends) or rx (device receives)");
    pdo.direction = dir == "tx" ? PdoDirection::tx : PdoDirection::rx;
    pdo.cob_id_base = in_range<std::uint32_t>(src, n, "cob_id", 0x001, 0x7FF);
    pdo.transmission_type = in_range<std::uint8_t>(src, n, "transmission_type", 0, 255);
    const YAML::Node mapping = n["mapping"];
    src.expect_sequence(mapping, "mapping");
    for (const auto& e : mapping) {
      const auto entry = canopen::PdoEntry::from_u32(src.as<std::uint32_t>(e, "mapping"));
      if (!entry.is_dummy()) {
        const ObjectDef* obj = p.object(entry.index, entry.sub);
        if (obj == nullptr) src.fail(e, "mapping entry names an object the profile does not define");
        if (canopen::bit_size(obj->type) != entry.bits) src.fail(e, "mapping entry length differs from the object's type");
      }
      pdo.mapping.push_back(entry);
    }
    if (auto m = canopen::PdoMapping::create(pdo.mapping); !m) src.fail(mapping, m.error().message);
    p.pdos.push_back(std::move(pdo));
  }
}

}  // namespace

Result<Profile> parse_profile(const std::string& yaml_text, const std::string& source) {
  const YamlSource src(source);
  try {
    const YAML::Node root = src.parse(yaml_text);
    src.check_keys(root, "profile", {"profile", "version", "device", "title", "device_type", "objects", "bitsets", "pdos"});
    Profile p;
    p.id = src.required<std::string>(root, "profile", "profile");
    p.version = src.required<std::string>(root, "version", "profile");
    p.device = src.required<std::string>(root, "device", "profile");
    p.title = src.optional<std::string>(root, "title").value_or("");
    p.device_type = src.required<std::uint32_t>(root, "device_type", "profile");
    parse_objects(src, src.required<YAML::Node>(root, "objects", "profile"), p);
    if (root["bitsets"]) parse_bitsets(src, root["bitsets"], p);
    if (root["pdos"]) parse_pdos(src, root["pdos"], p);
    return p;
  } catch (const ConfigError& e) {
    return make_error(e.what());
  }
}

ProfileRegistry ProfileRegistry::builtin() {
  ProfileRegistry registry;
  for (const auto& [name, text] : builtin_profile_texts()) {
    auto p = parse_profile(std::string(text), "built-in " + std::string(name));
    if (!p) throw std::logic_error("broken built-in profile: " + p.error().message);
    registry.add(std::move(*p));
  }
  return registry;
}

Result<void> ProfileRegistry::add_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return make_error(path + ": cannot open profile file");
  std::stringstream text;
  text << in.rdbuf();
  auto p = parse_profile(text.str(), path);
  if (!p) return p.error();
  add(std::move(*p));
  return {};
}

void ProfileRegistry::add(Profile profile) {
  for (auto& existing : profiles_) {
    if (existing.key() == profile.key()) {
      existing = std::move(profile);  // a file given by the user replaces the built-in one
      return;
    }
  }
  profiles_.push_back(std::move(profile));
}

const Profile* ProfileRegistry::find(std::string_view id, std::string_view version) const {
  for (const auto& p : profiles_) {
    if (p.id == id && p.version == version) return &p;
  }
  return nullptr;
}

std::vector<std::string> ProfileRegistry::keys() const {
  std::vector<std::string> out;
  for (const auto& p : profiles_) out.push_back(p.key());
  return out;
}

}  // namespace lb::profiles
