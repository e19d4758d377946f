#pragma once
// What a master may write of a PDO's communication and mapping parameters (1400h..1BFFh). CiA 301
// leaves all of it rw; device profiles fix parts so that devices stay plug-and-play (CiA 420: the
// default mapping entries const, the COB-IDs ro). A profile file states it per PDO (profiles/).

#include <cstdint>
#include <string_view>
#include <vector>

namespace lb::canopen {

enum class PdoAccess {
  rw,         // writable
  rw_preop,   // "rw (constant in NMT operational state)": writable while not operational
  valid_bit,  // COB-ID only: bit 31 (valid / not valid) may be written, the identifier is fixed
  fixed,      // const or ro: the device's value cannot be changed
  none,       // the device does not implement the entry (e.g. a feeder RPDO's inhibit time)
};

constexpr std::string_view to_string(PdoAccess access) {
  switch (access) {
    case PdoAccess::rw: return "rw";
    case PdoAccess::rw_preop: return "rw (constant in NMT operational state)";
    case PdoAccess::valid_bit: return "fixed except its valid bit";
    case PdoAccess::fixed: return "const";
    case PdoAccess::none: return "not implemented";
  }
  return "?";
}

constexpr bool writable(PdoAccess access) { return access == PdoAccess::rw || access == PdoAccess::rw_preop; }

struct PdoRules {
  PdoAccess cob_id = PdoAccess::rw;
  PdoAccess transmission_type = PdoAccess::rw;
  PdoAccess inhibit_time = PdoAccess::rw;
  PdoAccess event_timer = PdoAccess::rw;
  PdoAccess mapping_count = PdoAccess::rw;  // sub 0 of the mapping parameter
  PdoAccess mapping = PdoAccess::rw;        // the entries sub 1..n
  // The values sub 0 may take ("00h, 02h to 03h"); empty: 0 up to the entries the device has.
  std::vector<std::uint8_t> mapping_counts;
  // Entries after the profile's default ones whose object the manufacturer chooses (CiA 420-4 3.1
  // TPDO1 sub 3: "one and only one manufacturer-specific process data"): their value is the
  // device's, mapped or not by sub 0.
  unsigned manufacturer_entries = 0;
};

}  // namespace lb::canopen
