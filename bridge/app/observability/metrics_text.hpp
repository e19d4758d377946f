#pragma once
// /metrics: the line as Prometheus reads it (text exposition format 0.0.4), made from a LineView
// alone: a pure function, called on the server's threads.

#include <string>

#include "app/observability/line_view.hpp"

namespace lb::app::obs {

std::string render_metrics(const LineView& view);

}  // namespace lb::app::obs
