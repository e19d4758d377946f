#pragma once
// A device's PDO bound to a gateway's process image after the checks a PDO found on a device
// (pdo_config: adopt) must pass: every mapped object is one of the profile's, of its size and
// direction, and an RPDO carries only objects the gateway holds (it would send 0 for any other).

#include <fmt/format.h>

#include <stdexcept>
#include <string>

#include "base/result.hpp"
#include "canopen/pdo_parameters.hpp"
#include "canopen/process_image.hpp"
#include "gateways/codecs/other_values.hpp"
#include "profiles/line_config.hpp"

namespace lb::gateways {

// A codec's PDO as the line file gives it, bound at start-up; the objects the typed status does not
// name get their slots first (others, index: the PDO's). A mapping that does not decode ends start-up.
inline canopen::PdoBinding bind_line_pdo(const profiles::Profile& profile, canopen::ProcessImage& image,
                                         const profiles::DevicePdo& pdo, OtherValues& others, std::size_t index) {
  others.bind(index, pdo, image);
  auto mapping = canopen::PdoMapping::create(pdo.mapping);
  if (!mapping) throw std::runtime_error("profile " + profile.key() + " " + pdo.name + ": " + mapping.error().message);
  return canopen::PdoBinding(std::move(*mapping), image);
}

inline Result<canopen::PdoBinding> bind_device_pdo(const profiles::Profile& profile, const canopen::ProcessImage& image,
                                                   const profiles::DevicePdo& pdo) {
  auto mapping = canopen::PdoMapping::create(pdo.mapping);
  if (!mapping) return make_error(pdo.name + ": " + mapping.error().message);
  const bool rx = pdo.direction == profiles::PdoDirection::rx;
  for (const auto& e : pdo.mapping) {
    const auto entry = canopen::describe_entry(e);
    if (e.is_dummy()) {
      if (!rx)
        return make_error(fmt::format("{} maps the dummy entry {}: only an RPDO can skip bits", pdo.name, entry));
      continue;
    }
    const profiles::ObjectDef* obj = profile.object(e.index, e.sub);
    if (obj == nullptr) {
      return make_error(fmt::format("{} maps {}, an object profile {} does not define: the bridge could not decode it "
                                    "(name it under the device's objects: in the line file)",
                                    pdo.name, entry, profile.key()));
    }
    if (canopen::bit_size(obj->type) != e.bits) {
      return make_error(fmt::format("{} maps {} with {} bits, but {} is {}", pdo.name, entry, e.bits, obj->name,
                                    canopen::to_string(obj->type)));
    }
    if (rx && image.find(e.index, e.sub) == canopen::ProcessImage::npos) {
      return make_error(fmt::format("{} maps {} ({}), which the bridge does not send: it would send 0 for it", pdo.name,
                                    obj->name, entry));
    }
  }
  return canopen::PdoBinding(std::move(*mapping), image);
}

// A codec's PDO (`def`, `binding`) taking the parameters its device's boot found: a mapping that is
// the line's own was checked at start-up; another one is bound after the checks above, and on a
// refusal nothing changes.
// Objects the typed status does not name get their slots (others, index: the PDO's) before the
// binding, so they are decoded and published too.
inline Result<void> use_device_pdo(const profiles::Profile& profile, canopen::ProcessImage& image,
                                   profiles::DevicePdo& def, canopen::PdoBinding& binding,
                                   const profiles::DevicePdo& actual, OtherValues& others, std::size_t index) {
  if (actual.mapping != def.mapping) {
    others.bind(index, actual, image);
    auto bound = bind_device_pdo(profile, image, actual);
    if (!bound) {
      others.bind(index, def, image);
      return bound.error();
    }
    binding = std::move(*bound);
  }
  def = actual;
  return {};
}

}  // namespace lb::gateways
