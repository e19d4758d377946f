#pragma once
// /: the line's status page, one HTML document made from a LineView alone (a pure function, called
// on the server's threads). It loads nothing from anywhere (its style is inline, no script, no
// font) and refreshes itself every 2 s. Every state is written in words; colour is only a second
// cue. Every string that comes from the line file or the bus is HTML-escaped.

#include <string>
#include <string_view>

#include "app/observability/line_view.hpp"

namespace lb::app::obs {

inline constexpr int kStatusPageRefreshSeconds = 2;

std::string render_status_page(const LineView& view);

// &, <, >, " and ' as entities: text and attribute values alike.
std::string html_escape(std::string_view text);

// A CiA 302-2 boot error letter (A..O) in words.
std::string_view boot_error_meaning(char letter);

}  // namespace lb::app::obs
