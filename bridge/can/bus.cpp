#include "can/bus.hpp"

#include "can/listen_only_bus.hpp"
#include "can/log_bus.hpp"
#include "can/socketcan_bus.hpp"
#include "can/virtual_bus.hpp"

namespace lb::can {

Result<void> check_bus_uri(std::string_view uri) {
  const auto colon = uri.find(':');
  const std::string_view scheme = colon == std::string_view::npos ? std::string_view{} : uri.substr(0, colon);
  const std::string_view name = colon == std::string_view::npos ? std::string_view{} : uri.substr(colon + 1);
  if (scheme != "socketcan" && scheme != "virtual" && scheme != "log") {
    return make_error("unknown scheme in '" + std::string(uri.substr(0, 100)) +
                      "': interface must be socketcan:<ifname>, virtual:<name> or log:<file>");
  }
  if (name.empty()) return make_error("interface '" + std::string(uri) + "': the name after ':' is empty");
  if (scheme == "socketcan") return SocketCanBus::check_name(name);
  if (scheme == "virtual") return VirtualBus::check_name(name);
  if (auto spec = LogBus::parse_spec(name); !spec) return spec.error();
  return {};
}

namespace {

Result<std::unique_ptr<Bus>> open_medium(std::string_view uri) {
  if (auto ok = check_bus_uri(uri); !ok) return ok.error();
  const std::string_view scheme = uri.substr(0, uri.find(':'));
  const std::string_view name = uri.substr(uri.find(':') + 1);

  if (scheme == "socketcan") {
    auto bus = SocketCanBus::open(name);
    if (!bus) return bus.error();
    return std::unique_ptr<Bus>(std::move(*bus));
  }
  if (scheme == "log") {
    // Receive-only by itself: it refuses every send like ListenOnlyBus, whatever the access.
    auto bus = LogBus::open(name);
    if (!bus) return bus.error();
    return std::unique_ptr<Bus>(std::move(*bus));
  }
  auto bus = VirtualBus::open(name);
  if (!bus) return bus.error();
  return std::unique_ptr<Bus>(std::move(*bus));
}

}  // namespace

Result<std::unique_ptr<Bus>> open_bus(std::string_view uri, BusAccess access) {
  auto bus = open_medium(uri);
  if (!bus || access == BusAccess::read_write) return bus;
  return std::unique_ptr<Bus>(std::make_unique<ListenOnlyBus>(std::move(*bus)));
}

}  // namespace lb::can
