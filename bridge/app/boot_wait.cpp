#include "app/boot_wait.hpp"

#include <fmt/format.h>

#include <array>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string_view>

#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::app {

namespace msg = linebridge_msgs::msg;

bool boot_settled(const msg::NodeDiagnostics& node) {
  const std::string_view boot = node.boot_state();
  if (boot == "started" || boot.starts_with("configured")) return true;
  // canopen::to_string(NodeState) of the states in which a boot is under way or will be.
  constexpr std::array<std::string_view, 4> kUnderWay{"unknown", "booting", "resetting", "lost"};
  for (const auto state : kUnderWay) {
    if (node.node_state() == state) return false;
  }
  return !node.node_state().empty();
}

Result<void> wait_for_boot(ddsl::Participant& dds, const std::string& line, const std::string& device,
                           std::chrono::steady_clock::duration timeout) {
  std::mutex m;
  std::condition_variable cv;
  std::optional<msg::NodeDiagnostics> last;
  const auto topic = ddsl::topic_name(line, ddsl::kBridgeNamespace, "diagnostics");
  auto sub = dds.subscribe_scoped<msg::DiagnosticsPubSubType>(topic, ddsl::QosKind::state,
                                                              [&](const msg::Diagnostics& d, const auto&) {
                                                                for (const auto& n : d.nodes()) {
                                                                  if (n.device() != device) continue;
                                                                  {
                                                                    std::lock_guard lock(m);
                                                                    last = n;
                                                                  }
                                                                  cv.notify_all();
                                                                }
                                                              });
  if (!sub) return make_error(sub.error().message);
  std::unique_lock lock(m);
  if (cv.wait_for(lock, timeout, [&] { return last && boot_settled(*last); })) return {};
  if (!last)
    return make_error(
        fmt::format("{}: no diagnostics naming it on {} (is the bridge running for line {}?)", device, topic, line));
  return make_error(
      fmt::format("{}: its boot has not passed ({}: {})", device, last->node_state(), last->boot_state()));
}

}  // namespace lb::app
