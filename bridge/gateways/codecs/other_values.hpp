#pragma once
// The objects a device's received PDOs carry that its typed status does not name: a
// manufacturer-specific object the line file names (device `objects:`), a profile object an
// integrator mapped, or one a device's own mapping carries (pdo_config: adopt). They are decoded
// into the codec's image like the typed ones and published by name, in engineering units, in the
// status's `other_values`, so no mapped value is ever dropped.
//
// A codec constructs this after it bound its typed objects (those slots are the typed ones), and
// binds each received PDO here before it binds the PDO itself (so the slots exist to decode into).
// Received PDOs: TPDOs, and on a monitor bus the RPDOs too. An RPDO the bridge sends never gets
// such slots: it would send 0 for them (pdo_binding.hpp refuses that mapping instead).

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include "canopen/data_type.hpp"
#include "canopen/process_image.hpp"
#include "msgs/common.h"
#include "profiles/line_config.hpp"

namespace lb::gateways {

class OtherValues {
 public:
  OtherValues(const profiles::Profile& profile, const canopen::ProcessImage& image, bool rpdos_received)
      : profile_(profile), typed_slots_(image.size()), rpdos_received_(rpdos_received) {}

  // Construction or boot (the image's thread): PDO `index` as it is decoded from now on.
  void bind(std::size_t index, const profiles::DevicePdo& pdo, canopen::ProcessImage& image) {
    if (per_pdo_.size() <= index) per_pdo_.resize(index + 1);
    auto& values = per_pdo_[index];
    values.clear();
    if (pdo.direction == profiles::PdoDirection::rx && !rpdos_received_) return;
    for (const auto& e : pdo.mapping) {
      if (e.is_dummy()) continue;
      const profiles::ObjectDef* def = profile_.object(e.index, e.sub);
      if (def == nullptr) continue;  // refused before it gets here (pdo_binding.hpp, line_config)
      const std::size_t slot = image.slot(e.index, e.sub);
      if (slot >= typed_slots_) values.push_back({def, slot, pdo.name});
    }
  }

  void fill(const canopen::ProcessImage& image, std::vector<linebridge_msgs::msg::ProcessValue>& out) const {
    out.clear();
    std::vector<std::size_t> seen;
    for (const auto& values : per_pdo_) {
      for (const auto& v : values) {
        if (std::find(seen.begin(), seen.end(), v.slot) != seen.end() || out.size() == kMax) continue;
        seen.push_back(v.slot);
        const std::uint64_t raw = image.get(v.slot);
        const unsigned bits = canopen::bit_size(v.def->type);
        linebridge_msgs::msg::ProcessValue m;
        m.name(v.def->name);
        m.index(v.def->index);
        m.sub_index(v.def->sub);
        m.pdo(v.pdo);
        m.value(v.def->to_engineering(raw));
        m.unit(v.def->eng_unit);
        m.raw(canopen::is_signed_integer(v.def->type) ? canopen::sign_extend(raw, bits)
                                                      : static_cast<std::int64_t>(raw));
        out.push_back(std::move(m));
      }
    }
  }

 private:
  static constexpr std::size_t kMax = 16;  // the DDS bound; a PDO carries at most 64 bits anyway
  struct Value {
    const profiles::ObjectDef* def;
    std::size_t slot;
    std::string pdo;
  };

  const profiles::Profile& profile_;
  std::size_t typed_slots_;
  bool rpdos_received_;
  std::vector<std::vector<Value>> per_pdo_;
};

}  // namespace lb::gateways
