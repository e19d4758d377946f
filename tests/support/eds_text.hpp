#pragma once
// The EDS (CiA 306) of a device that is exactly its profile, as linebridge-sim plays it (identity
// 4C42 0000h, product 0420 000xh, revision 0001 0000h): a starting point that tests change entry
// by entry to make a vendor's file that differs.

#include <fmt/format.h>

#include <map>
#include <set>
#include <string>

#include "profiles/profile.hpp"

namespace lb::test {

inline std::string eds_access(profiles::Access a) {
  switch (a) {
    case profiles::Access::ro: return "ro";
    case profiles::Access::wo: return "wo";
    case profiles::Access::rw: return "rw";
    case profiles::Access::const_: return "const";
  }
  return "ro";
}

inline std::uint16_t eds_type_code(canopen::DataType t) {
  using canopen::DataType;
  switch (t) {
    case DataType::boolean: return 0x0001;
    case DataType::integer8: return 0x0002;
    case DataType::integer16: return 0x0003;
    case DataType::integer32: return 0x0004;
    case DataType::integer64: return 0x0015;
    case DataType::unsigned8: return 0x0005;
    case DataType::unsigned16: return 0x0006;
    case DataType::unsigned32: return 0x0007;
    case DataType::unsigned64: return 0x001B;
    case DataType::real32: return 0x0008;
    case DataType::real64: return 0x0011;
    case DataType::visible_string: return 0x0009;
    case DataType::octet_string: return 0x000A;
  }
  return 0;
}

inline std::string eds_var(const std::string& section, const std::string& name, std::uint16_t type,
                           const std::string& access, const std::string& value, bool mappable) {
  return fmt::format(
      "[{}]\nParameterName={}\nObjectType=0x7\nDataType=0x{:04X}\nAccessType={}\nDefaultValue={}\nPDOMapping={}\n\n",
      section, name, type, access, value, mappable ? 1 : 0);
}

inline std::string eds_of(const profiles::Profile& p, std::uint32_t product_code) {
  std::string out =
      fmt::format("[FileInfo]\nFileName=test.eds\nDescription=as the profile says ; comments are allowed\n\n"
                  "[DeviceInfo]\nVendorName=linebridge test\nVendorNumber=0x4C420000\nProductName={} "
                  "simulated\nProductNumber=0x{:08X}\n"
                  "RevisionNumber=0x00010000\nBaudRate_500=1\n\n",
                  p.device, product_code);
  out += eds_var("1000", "Device type", 0x0007, "ro", fmt::format("0x{:08X}", p.device_type), false);
  out += "[1018]\nParameterName=Identity object\nObjectType=0x9\nSubNumber=5\n\n";
  out += eds_var("1018sub0", "Highest sub-index supported", 0x0005, "ro", "4", false);
  out += eds_var("1018sub1", "Vendor-ID", 0x0007, "ro", "0x4C420000", false);
  out += eds_var("1018sub2", "Product code", 0x0007, "ro", fmt::format("0x{:08X}", product_code), false);
  out += eds_var("1018sub3", "Revision number", 0x0007, "ro", "0x00010000", false);
  out += eds_var("1018sub4", "Serial number", 0x0007, "ro", "0", false);
  std::set<std::uint16_t> records;
  for (const auto& o : p.objects) {
    if (o.sub != 0) records.insert(o.index);
  }
  for (const auto& o : p.objects) {
    if (records.count(o.index) != 0 && o.sub == 0) {
      out += fmt::format("[{:04X}]\nParameterName={}\nObjectType=0x8\n\n", o.index, o.name);
    }
    const auto section = records.count(o.index) != 0 ? fmt::format("{:04X}sub{:X}", o.index, o.sub)
                                                     : fmt::format("{:04X}", o.index);
    out += eds_var(section, o.name, eds_type_code(o.type), eds_access(o.access), "0", o.index >= 0x6000);
  }
  for (const auto& pdo : p.pdos) {
    const auto comm = pdo.communication_index();
    const auto map = pdo.mapping_index();
    out += fmt::format("[{:04X}]\nParameterName={} communication parameter\nObjectType=0x9\nSubNumber=6\n\n", comm,
                       pdo.name);
    out += eds_var(fmt::format("{:04X}sub0", comm), "Highest sub-index supported", 0x0005, "const", "5", false);
    out += eds_var(fmt::format("{:04X}sub1", comm), "COB-ID", 0x0007, "rw",
                   fmt::format("{}$NODEID+0x{:X}",
                               pdo.validity == profiles::PdoValidity::not_valid ? "0x80000000+" : "", pdo.cob_id_base),
                   false);
    out += eds_var(fmt::format("{:04X}sub2", comm), "Transmission type", 0x0005, "rw",
                   std::to_string(pdo.transmission_type), false);
    out += eds_var(fmt::format("{:04X}sub3", comm), "Inhibit time", 0x0006, "rw", "0", false);
    out += eds_var(fmt::format("{:04X}sub5", comm), "Event timer", 0x0006, "rw", "0", false);
    out += fmt::format("[{:04X}]\nParameterName={} mapping parameter\nObjectType=0x9\n\n", map, pdo.name);
    out += eds_var(fmt::format("{:04X}sub0", map), "Number of mapped objects", 0x0005, "rw",
                   std::to_string(pdo.mapping.size()), false);
    for (std::size_t i = 0; i < pdo.mapping.size(); ++i) {
      out += eds_var(fmt::format("{:04X}sub{:X}", map, i + 1), "Mapped object", 0x0007, "const",
                     fmt::format("0x{:08X}", pdo.mapping[i].to_u32()), false);
    }
  }
  return out;
}

// Replaces the value of `key` in [section] (which must exist).
inline std::string eds_set(std::string eds, const std::string& section, const std::string& key,
                           const std::string& value) {
  const auto s = eds.find("[" + section + "]\n");
  if (s == std::string::npos) throw std::runtime_error("no section " + section);
  const auto k = eds.find("\n" + key + "=", s);
  const auto end = eds.find('\n', k + 1);
  eds.replace(k + 1, end - k - 1, key + "=" + value);
  return eds;
}

// Adds a key to [section] (a DCF's ParameterValue, for one).
inline std::string eds_add(std::string eds, const std::string& section, const std::string& key,
                           const std::string& value) {
  const auto s = eds.find("[" + section + "]\n");
  if (s == std::string::npos) throw std::runtime_error("no section " + section);
  eds.insert(s + section.size() + 3, key + "=" + value + "\n");
  return eds;
}

}  // namespace lb::test
