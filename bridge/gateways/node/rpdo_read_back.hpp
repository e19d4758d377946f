#pragma once
// What a running device holds in the objects one of its RPDOs maps, read back by SDO and packed as
// that RPDO's payload: the set values in force as the device has them. A restarted bridge that
// adopts a running device sends it this rather than zeros or a file's values it cannot trust
// (CiA 301: an RPDO's objects are the device's own, readable unless the profile makes them
// write-only). Dummy entries read as 0. Entries `read` marks false (write-only objects) are not
// read: they keep their value in `base`, a payload of this mapping (the kept values), so a device
// whose RPDO maps one write-only object still has every readable one, its enabling levels above
// all, from itself. Loop thread; `done` runs once, on the loop thread.

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "base/result.hpp"
#include "canopen/pdo_mapping.hpp"
#include "canopen/sdo_client.hpp"

namespace lb::gateways {

using ReadBackDone = std::function<void(Result<std::vector<std::uint8_t>>)>;
void read_back_rpdo(canopen::SdoClient& sdo, std::uint8_t node, const canopen::PdoMapping& mapping,
                    std::vector<bool> read, std::span<const std::uint8_t> base, ReadBackDone done);

}  // namespace lb::gateways
