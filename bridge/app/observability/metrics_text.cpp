#include "app/observability/metrics_text.hpp"

#include <fmt/format.h>

#include "app/version.hpp"

namespace lb::app::obs {

// The build only, for now: every other family is made from the diagnostics sample.
std::string render_metrics(const LineView& view) {
  // Line names are letters, digits and '_' (the line file's check): no label escaping is needed.
  return fmt::format("# HELP linebridge_build_info The bridge's version, and the line it serves.\n"
                     "# TYPE linebridge_build_info gauge\n"
                     "linebridge_build_info{{line=\"{}\",version=\"{}\"}} 1\n",
                     view.line, kVersion);
}

}  // namespace lb::app::obs
