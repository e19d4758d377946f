#pragma once
// Fast DDS's own warnings and errors in the bridge's log. By default Fast DDS prints only errors,
// to stdout, unthrottled, and keeps its warnings to itself: among them the ones that say a reader
// refused a sample ("Reached the maximum number of samples allowed by this reader's QoS"), which
// is all there is to see when a client's set value never reaches the bridge. Routed here, each
// gets a line in the bridge's log ("Fast DDS [CATEGORY] message"), at most a few a second per kind
// with the count of those held back, like every other repeated message of the bridge.
//
// Fast DDS's log is one per process: the route is taken for the lifetime of this object (one, in
// main) and given back, flushed, when it ends, before spdlog's loggers go.

#include <fastdds/dds/log/Log.hpp>

namespace lb::ddsl {

class FastDdsLogRoute {
 public:
  // verbosity: the least severe kind of Fast DDS message that is logged (Warning: warnings and errors).
  explicit FastDdsLogRoute(eprosima::fastdds::dds::Log::Kind verbosity = eprosima::fastdds::dds::Log::Kind::Warning);
  ~FastDdsLogRoute();
  FastDdsLogRoute(const FastDdsLogRoute&) = delete;
  FastDdsLogRoute& operator=(const FastDdsLogRoute&) = delete;
};

}  // namespace lb::ddsl
