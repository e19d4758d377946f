#pragma once
// How the bench programs name what they share, so that the line configuration one of them writes
// and the buses, topics and node-IDs the others use always agree.

#include <cstdint>
#include <cstdlib>
#include <string>

namespace lb::bench {

constexpr const char* kLine = "bench";
constexpr int kFirstNodeId = 10;  // devices get 10, 11, ...: distinct node-IDs within 1..127
constexpr int kMaxDevicesPerBus = 127 - kFirstNodeId + 1;

// prefix keeps the buses of one bench step apart from those of a step still shutting down.
inline std::string bus_uri(const std::string& prefix, int bus) {
  return "virtual:" + prefix + "-" + std::to_string(bus);
}
inline std::string bus_name(int bus) { return "bus" + std::to_string(bus); }
inline std::string device_name(int bus, int device) {
  return "b" + std::to_string(bus) + "saw" + std::to_string(device);
}
inline std::uint8_t node_id(int device) { return static_cast<std::uint8_t>(kFirstNodeId + device); }

// bench.sh --shared-memory: the line file bench-config writes (dds.shared_memory) and every bench
// participant add Fast DDS's shared-memory transport, so a figure can be measured on both.
inline bool shared_memory_transport() { return std::getenv("LINEBRIDGE_BENCH_SHARED_MEMORY") != nullptr; }

}  // namespace lb::bench
