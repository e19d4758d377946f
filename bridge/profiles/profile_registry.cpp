#include "profiles/profile_registry.hpp"

#include <algorithm>
#include <charconv>
#include <stdexcept>
#include <unordered_set>

#include <fmt/format.h>

#include "profiles/builtin_profiles.hpp"
#include "profiles/config_file.hpp"
#include "profiles/object_fields.hpp"
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
    src.fail(map[std::string(key)], std::string(key) + " " + std::to_string(v) + " is outside " + std::to_string(lo) +
                                        ".." + std::to_string(hi));
  }
  return static_cast<T>(v);
}

template <class T>
std::optional<T> optional_in_range(const YamlSource& src, const YAML::Node& map, std::string_view key, std::int64_t lo,
                                   std::int64_t hi) {
  if (!map[std::string(key)]) return std::nullopt;
  return in_range<T>(src, map, key, lo, hi);
}

std::string hex(std::uint64_t v, int digits = 4) { return fmt::format("{:0{}X}h", v, digits); }

// Names that become DDS field names and log words: one spelling, checked at load time.
bool is_snake_case(std::string_view s) {
  if (s.empty() || s.front() < 'a' || s.front() > 'z') return false;
  return std::all_of(s.begin(), s.end(),
                     [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_'; });
}

std::string snake_case_name(const YamlSource& src, const YAML::Node& node, std::string_view what) {
  auto name = src.as<std::string>(node, what);
  if (!is_snake_case(name)) {
    src.fail(node, std::string(what) + " '" + name + "' must be snake_case (a-z, 0-9, _; starting with a letter)");
  }
  return name;
}

std::uint64_t field_max(unsigned width) { return width >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << width) - 1; }

// A code as written in a value table: decimal, 0x hex or 0b binary (binary because the specs
// print 2-bit codes such as 10b).
std::optional<std::uint64_t> parse_number(std::string_view text) {
  int base = 10;
  if (text.size() > 2 && text[0] == '0') {
    if (text[1] == 'x' || text[1] == 'X') base = 16;
    if (text[1] == 'b' || text[1] == 'B') base = 2;
    if (base != 10) text.remove_prefix(2);
  }
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v, base);
  if (ec != std::errc{} || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return v;
}

// `values` (an enumeration: unlisted codes are invalid) or `special_values` (a number whose listed
// codes mean something else) of an object or field `width` bits wide.
std::optional<ValueTable> parse_value_table(const YamlSource& src, const YAML::Node& owner, unsigned width) {
  const YAML::Node values = owner["values"];
  const YAML::Node special = owner["special_values"];
  if (values && special)
    src.fail(special, "give either values (an enumeration) or special_values (a number), not both");
  if (!values && !special) return std::nullopt;
  const YAML::Node table = values ? values : special;
  src.expect_map(table, values ? "values" : "special_values");
  ValueTable out;
  out.exhaustive = static_cast<bool>(values);
  for (const auto& kv : table) {
    const auto text = kv.first.as<std::string>();
    const auto dots = text.find("..");
    const auto first = parse_number(std::string_view(text).substr(0, dots));
    const auto last = dots == std::string::npos ? first : parse_number(std::string_view(text).substr(dots + 2));
    if (!first || !last) {
      src.fail(kv.first, "value code '" + text + "' must be a number (12, 0x0C, 0b1100) or a range first..last");
    }
    if (*first > *last) src.fail(kv.first, "value range '" + text + "' runs backwards");
    if (*last > field_max(width)) {
      src.fail(kv.first, "value code '" + text + "' does not fit in " + std::to_string(width) + " bits");
    }
    ValueRange range{*first, *last, snake_case_name(src, kv.second, "value name")};
    for (const auto& other : out.ranges) {
      if (range.first <= other.last && other.first <= range.last) {
        src.fail(kv.first, "value code '" + text + "' overlaps " + other.name);
      }
    }
    out.ranges.push_back(std::move(range));
  }
  std::sort(out.ranges.begin(), out.ranges.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

}  // namespace

ObjectDef parse_object_fields(const YamlSource& src, const YAML::Node& o, const std::string& what) {
  ObjectDef def;
  def.index = in_range<std::uint16_t>(src, o, "index", 0x1000, 0xFFFF);
  def.sub = optional_in_range<std::uint8_t>(src, o, "sub", 0, 255).value_or(0);
  def.name = src.required<std::string>(o, "name", what);
  const auto type_text = src.required<std::string>(o, "type", what);
  const auto type = canopen::parse_data_type(type_text);
  if (!type) src.fail(o["type"], "unknown data type '" + type_text + "'");
  def.type = *type;
  def.access = o["access"] ? parse_access(src, o["access"]) : Access::ro;
  def.unit = src.optional<std::string>(o, "unit").value_or("");
  def.scale = src.optional<double>(o, "scale").value_or(1.0);
  if (def.scale == 0.0) src.fail(o["scale"], "scale must not be 0");
  def.eng_unit = src.optional<std::string>(o, "eng_unit").value_or(def.unit);
  def.min = src.optional<std::int64_t>(o, "min");
  def.max = src.optional<std::int64_t>(o, "max");
  def.mandatory = src.optional<bool>(o, "mandatory").value_or(true);
  const bool integer = canopen::is_signed_integer(def.type) || canopen::is_unsigned_integer(def.type);
  if ((o["values"] || o["special_values"]) && !integer) {
    src.fail(o["values"] ? o["values"] : o["special_values"],
             "named codes need an integer data type, not " + type_text);
  }
  if (auto table = parse_value_table(src, o, canopen::bit_size(def.type))) def.values = std::move(*table);
  return def;
}

namespace {

class ProfileLoader {
 public:
  ProfileLoader(const YamlSource& src, Profile& p) : src_(src), p_(p) {}

  void objects(const YAML::Node& list) {
    src_.expect_sequence(list, "objects");
    for (const auto& o : list) object(o);
  }

  void bitsets(const YAML::Node& map) {
    src_.expect_map(map, "bitsets");
    for (const auto& kv : map) bitset(kv.first.as<std::string>(), kv.second);
  }

  void pdos(const YAML::Node& list) {
    src_.expect_sequence(list, "pdos");
    for (const auto& n : list) pdo(n);
  }

 private:
  void object(const YAML::Node& o) {
    src_.check_keys(o, "object",
                    {"index", "sub", "name", "type", "access", "unit", "scale", "eng_unit", "min", "max", "array",
                     "mandatory", "values", "special_values", "enabling"});
    if (!o["access"]) src_.fail(o, "object: missing required key 'access'");
    ObjectDef def = parse_object_fields(src_, o, "object");
    def.enabling = src_.optional<bool>(o, "enabling").value_or(false);
    if (def.enabling && !def.writable())
      src_.fail(o["enabling"], "enabling: only an object the master writes can let a machine run");
    const auto sub = optional_in_range<std::uint8_t>(src_, o, "sub", 0, 255);

    const auto n = src_.optional<int>(o, "array");
    if (!n) {
      add(o, std::move(def));
      return;
    }
    // ARRAY objects: sub 0 holds the highest sub-index, subs 1..n the elements.
    if (*n < 1 || *n > 254) src_.fail(o["array"], "array size must be 1..254");
    if (sub) src_.fail(o["sub"], "an array defines its subs (0 and 1.." + std::to_string(*n) + "): drop sub");
    arrays_.push_back(def.index);
    ObjectDef count;
    count.index = def.index;
    count.name = def.name + "_count";
    count.type = canopen::DataType::unsigned8;
    count.access = Access::const_;
    count.mandatory = def.mandatory;
    add(o, std::move(count));
    for (int i = 1; i <= *n; ++i) {
      ObjectDef element = def;
      element.sub = static_cast<std::uint8_t>(i);
      element.name = def.name + "_" + std::to_string(i);
      // The profiles' ARRAY pattern: sub 1 is mandatory with the object, further elements optional;
      // sub 0 tells how many a device has.
      element.mandatory = def.mandatory && i == 1;
      add(o, std::move(element));
    }
  }

  void add(const YAML::Node& o, ObjectDef def) {
    if (!names_.insert(def.name).second) src_.fail(o["name"], "duplicate object name '" + def.name + "'");
    if (!keys_.insert(std::uint32_t{def.index} << 8 | def.sub).second) {
      src_.fail(o["index"], "object " + hex(def.index) + " sub " + std::to_string(def.sub) + " is defined twice");
    }
    p_.objects.push_back(std::move(def));
  }

  bool is_array(std::uint16_t index) const { return std::find(arrays_.begin(), arrays_.end(), index) != arrays_.end(); }

  void bitset(std::string name, const YAML::Node& node) {
    BitSet set;
    set.name = std::move(name);
    src_.check_keys(node, "bitset " + set.name, {"object", "sub", "bits", "enabling", "stopping"});
    set.index = in_range<std::uint16_t>(src_, node, "object", 0x1000, 0xFFFF);
    const auto sub = optional_in_range<std::uint8_t>(src_, node, "sub", 0, 255);
    // Without a sub, a bit set of an ARRAY describes every element (feeder n at sub n).
    set.every_element = !sub && is_array(set.index);
    set.sub = sub.value_or(0);
    const ObjectDef* obj = p_.object(set.index, set.every_element ? 1 : set.sub);
    if (obj == nullptr) {
      src_.fail(sub ? node["sub"] : node["object"],
                "bitset " + set.name + " names an object the profile does not define");
    }
    if (!canopen::is_signed_integer(obj->type) && !canopen::is_unsigned_integer(obj->type)) {
      src_.fail(node["object"],
                "bitset " + set.name + " needs an integer object, not " + std::string(canopen::to_string(obj->type)));
    }
    const unsigned word = canopen::bit_size(obj->type);
    const YAML::Node bits = node["bits"];
    if (!bits) src_.fail(node, "bitset " + set.name + ": missing required key 'bits'");
    src_.expect_map(bits, "bits");
    for (const auto& b : bits) set.bits.push_back(field(set, b.first, b.second, word));
    // By name: the levels that let the machine run (what a power loss must not bring back), and
    // the commands that stop it (what is never refused while the device is heard).
    mark(node, set, *obj, "enabling", &BitField::enabling);
    mark(node, set, *obj, "stopping", &BitField::stopping);
    p_.bitsets.push_back(std::move(set));
  }

  void mark(const YAML::Node& node, BitSet& set, const ObjectDef& obj, const char* key, bool BitField::*flag) const {
    const YAML::Node names = node[key];
    if (!names) return;
    src_.expect_sequence(names, key);
    if (!obj.writable()) src_.fail(names, std::string(key) + ": bitset " + set.name + " is not written by the master");
    for (const auto& e : names) {
      const auto name = src_.as<std::string>(e, key);
      const auto f = std::find_if(set.bits.begin(), set.bits.end(), [&](const BitField& b) { return b.name == name; });
      if (f == set.bits.end()) src_.fail(e, std::string(key) + ": bitset " + set.name + " has no field '" + name + "'");
      (*f).*flag = true;
    }
  }

  BitField field(const BitSet& set, const YAML::Node& key, const YAML::Node& value, unsigned word) const {
    BitField f;
    f.name = key.as<std::string>();
    const YAML::Node at = value.IsMap() ? value["bit"] : value;
    if (value.IsMap()) {
      src_.check_keys(value, "field " + f.name,
                      {"bit", "width", "unit", "scale", "eng_unit", "min", "max", "values", "special_values"});
      if (!at) src_.fail(value, "field " + f.name + ": missing required key 'bit'");
      f.width = optional_in_range<unsigned>(src_, value, "width", 1, 64).value_or(1);
      f.unit = src_.optional<std::string>(value, "unit").value_or("");
      f.scale = src_.optional<double>(value, "scale").value_or(1.0);
      if (f.scale == 0.0) src_.fail(value["scale"], "scale must not be 0");
      f.eng_unit = src_.optional<std::string>(value, "eng_unit").value_or(f.unit);
      f.min = src_.optional<std::int64_t>(value, "min");
      f.max = src_.optional<std::int64_t>(value, "max");
      if ((f.min || f.max) && f.width > 63)
        src_.fail(value, "field " + f.name + ": a range needs a field of at most 63 bits");
      if (auto table = parse_value_table(src_, value, f.width)) f.values = std::move(*table);
    }
    f.bit = src_.as<unsigned>(at, f.name);
    const auto span = [](const BitField& x) {
      return x.width == 1 ? "bit " + std::to_string(x.bit)
                          : "bits " + std::to_string(x.bit + x.width - 1) + ".." + std::to_string(x.bit);
    };
    if (f.bit >= word || f.width > word - f.bit) {
      src_.fail(at, span(f) + " does not exist in a " + std::to_string(word) + "-bit word");
    }
    for (const auto& other : set.bits) {
      if (other.name == f.name) src_.fail(key, "duplicate bit name '" + f.name + "'");
      if ((other.mask() & f.mask()) == 0) continue;
      if (f.width == 1 && other.width == 1) src_.fail(at, "bit " + std::to_string(f.bit) + " is already " + other.name);
      src_.fail(at, span(f) + (f.width == 1 ? " overlaps " : " overlap ") + other.name + " (" + span(other) + ")");
    }
    return f;
  }

  void pdo(const YAML::Node& n) {
    src_.check_keys(n, "pdo",
                    {"name", "direction", "cob_id", "transmission_type", "mapping", "valid", "mandatory",
                     "manufacturer_data", "access", "mapping_counts", "manufacturer_entries"});
    PdoDef pdo;
    pdo.name = src_.required<std::string>(n, "name", "pdo");
    const auto dir = src_.required<std::string>(n, "direction", "pdo");
    if (dir != "tx" && dir != "rx")
      src_.fail(n["direction"], "direction must be tx (device sends) or rx (device receives)");
    pdo.direction = dir == "tx" ? PdoDirection::tx : PdoDirection::rx;
    // The name is the CiA 301 number: tpdo3 is 1802h/1A02h, rpdo1 1400h/1600h.
    const std::string prefix = dir == "tx" ? "tpdo" : "rpdo";
    const auto number = pdo.name.rfind(prefix, 0) == 0 ? parse_number(std::string_view(pdo.name).substr(4))
                                                       : std::nullopt;
    if (!number || *number < 1 || *number > 512 || pdo.name[4] == '0') {
      src_.fail(n["name"], "a " + std::string(dir == "tx" ? "TPDO" : "RPDO") + " is named " + prefix + "1.." + prefix +
                               "512 (its CiA 301 number), not '" + pdo.name + "'");
    }
    for (const auto& other : p_.pdos) {
      if (other.name == pdo.name) src_.fail(n["name"], "pdo '" + pdo.name + "' is defined twice");
    }
    // The base of the predefined connection set: every node-ID (up to 127) is added to it, and the
    // sum must still be an 11-bit identifier (found by fuzz_profile: 7FFh gave 87Eh for node 127).
    pdo.cob_id_base = in_range<std::uint32_t>(src_, n, "cob_id", 0x001, 0x7FF - 127);
    pdo.transmission_type = in_range<std::uint8_t>(src_, n, "transmission_type", 0, 255);
    if (const YAML::Node v = n["valid"]) {
      const auto text = src_.as<std::string>(v, "valid");
      if (text == "true")
        pdo.validity = PdoValidity::valid;
      else if (text == "false")
        pdo.validity = PdoValidity::not_valid;
      else if (text == "either")
        pdo.validity = PdoValidity::either;
      else
        src_.fail(v, "valid must be true, false or either (COB-ID bit 31 as the device starts), not '" + text + "'");
    }
    pdo.mandatory = src_.optional<bool>(n, "mandatory").value_or(true);
    const YAML::Node mapping = n["mapping"];
    if (!mapping) src_.fail(n, "pdo: missing required key 'mapping'");
    src_.expect_sequence(mapping, "mapping");
    for (const auto& e : mapping) {
      const auto entry = canopen::PdoEntry::from_u32(src_.as<std::uint32_t>(e, "mapping"));
      if (!entry.is_dummy()) {
        const ObjectDef* obj = p_.object(entry.index, entry.sub);
        if (obj == nullptr) src_.fail(e, "mapping entry names an object the profile does not define");
        if (canopen::bit_size(obj->type) != entry.bits)
          src_.fail(e, "mapping entry length differs from the object's type");
        // A TPDO carries what the device reports, an RPDO what it is told.
        if (pdo.direction == PdoDirection::tx && !obj->readable()) {
          src_.fail(e, "a TPDO cannot carry " + obj->name + ", which is write-only");
        }
        if (pdo.direction == PdoDirection::rx && !obj->writable()) {
          src_.fail(e, "an RPDO cannot carry " + obj->name + ", which is " + std::string(to_string(obj->access)));
        }
      }
      pdo.mapping.push_back(entry);
    }
    if (auto m = canopen::PdoMapping::create(pdo.mapping); !m) src_.fail(mapping, m.error().message);
    if (const YAML::Node md = n["manufacturer_data"]) {
      src_.check_keys(md, "manufacturer_data", {"name", "bits"});
      if (!md["name"]) src_.fail(md, "manufacturer_data: missing required key 'name'");
      if (!md["bits"]) src_.fail(md, "manufacturer_data: missing required key 'bits'");
      PdoTail tail{snake_case_name(src_, md["name"], "manufacturer_data name"), 0};
      const unsigned used = pdo.mapped_bits();
      tail.bits = in_range<unsigned>(src_, md, "bits", 1, 64);
      if (used + tail.bits > 64) {
        src_.fail(md["bits"], "manufacturer data of " + std::to_string(tail.bits) +
                                  " bits does not fit: the mapping uses " + std::to_string(used) + " of 64 bits");
      }
      pdo.manufacturer_data = std::move(tail);
    }
    if (const YAML::Node a = n["access"]) pdo.rules = pdo_rules(a);
    if (const YAML::Node counts = n["mapping_counts"]) {
      src_.expect_sequence(counts, "mapping_counts");
      for (const auto& c : counts) {
        const auto v = src_.as<unsigned>(c, "mapping_counts");
        if (v > 64) src_.fail(c, "mapping_counts: a PDO maps at most 64 objects");
        pdo.rules.mapping_counts.push_back(static_cast<std::uint8_t>(v));
      }
    }
    if (n["manufacturer_entries"])
      pdo.rules.manufacturer_entries = in_range<unsigned>(src_, n, "manufacturer_entries", 0, 63);
    const auto most = static_cast<unsigned>(pdo.mapping.size()) + pdo.rules.manufacturer_entries;
    for (const auto c : pdo.rules.mapping_counts) {
      if (c > most) {
        src_.fail(n["mapping_counts"], "mapping_counts: " + std::to_string(c) + " entries, but the PDO has " +
                                           std::to_string(pdo.mapping.size()) + " default and " +
                                           std::to_string(pdo.rules.manufacturer_entries) +
                                           " manufacturer-specific ones");
      }
    }
    p_.pdos.push_back(std::move(pdo));
  }

  // access: {cob_id, transmission_type, inhibit_time, event_timer, mapping_count, mapping}, each
  // rw, rw_preop, const, ro or none (cob_id also valid_bit); what is not given stays CiA 301's rw.
  PdoRules pdo_rules(const YAML::Node& a) const {
    src_.check_keys(a, "pdo access",
                    {"cob_id", "transmission_type", "inhibit_time", "event_timer", "mapping_count", "mapping"});
    PdoRules r;
    const auto entry = [&](std::string_view key, PdoAccess& out, bool may_be_absent) {
      const YAML::Node v = a[std::string(key)];
      if (!v) return;
      const auto text = src_.as<std::string>(v, key);
      if (text == "rw")
        out = PdoAccess::rw;
      else if (text == "rw_preop")
        out = PdoAccess::rw_preop;
      else if (text == "const" || text == "ro")
        out = PdoAccess::fixed;
      else if (text == "valid_bit" && key == "cob_id")
        out = PdoAccess::valid_bit;
      else if (text == "none" && may_be_absent)
        out = PdoAccess::none;
      else {
        src_.fail(v, "access of " + std::string(key) + " must be rw, rw_preop, const or ro" +
                         (key == "cob_id" ? ", or valid_bit" : "") + (may_be_absent ? ", or none" : "") + ", not '" +
                         text + "'");
      }
    };
    entry("cob_id", r.cob_id, false);
    entry("transmission_type", r.transmission_type, false);
    entry("inhibit_time", r.inhibit_time, true);
    entry("event_timer", r.event_timer, true);
    entry("mapping_count", r.mapping_count, false);
    entry("mapping", r.mapping, false);
    return r;
  }

  const YamlSource& src_;
  Profile& p_;
  std::unordered_set<std::string> names_;
  std::unordered_set<std::uint32_t> keys_;  // index << 8 | sub
  std::vector<std::uint16_t> arrays_;       // indices declared with `array:`
};

}  // namespace

Result<Profile> parse_profile(const std::string& yaml_text, const std::string& source) {
  const YamlSource src(source);
  try {
    const YAML::Node root = src.parse(yaml_text);
    src.check_keys(root, "profile",
                   {"profile", "version", "device", "title", "device_type", "objects", "bitsets", "pdos"});
    Profile p;
    p.id = src.required<std::string>(root, "profile", "profile");
    p.version = src.required<std::string>(root, "version", "profile");
    p.device = src.required<std::string>(root, "device", "profile");
    p.title = src.optional<std::string>(root, "title").value_or("");
    p.device_type = src.required<std::uint32_t>(root, "device_type", "profile");
    ProfileLoader loader(src, p);
    loader.objects(src.required<YAML::Node>(root, "objects", "profile"));
    if (root["bitsets"]) loader.bitsets(root["bitsets"]);
    if (root["pdos"]) loader.pdos(root["pdos"]);
    return p;
  } catch (const ConfigError& e) {
    return make_error(e.what());
  } catch (const YAML::Exception& e) {  // a conversion the checks missed: still an error, not an abort
    return make_error(source + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1) + ": " +
                      e.msg);
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

Result<Profile> load_profile_file(const std::string& path) {
  auto text = read_config_file(path, "profile file");
  if (!text) return text.error();
  return parse_profile(*text, path);
}

Result<void> ProfileRegistry::add_file(const std::string& path) {
  auto p = load_profile_file(path);
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
