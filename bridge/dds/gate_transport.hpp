#pragma once
// A participant's discovery gate (discovery_gate.hpp) in front of one of its Fast DDS transports:
// Fast DDS's ChainingTransport over the real one (UDPv4 as the bridge configures it, or a site
// profile's), every received message inspected before Fast DDS reads it, sends untouched.
// Evictions (an evicted participant's announcement with its lease ended) are handed to Fast DDS on
// a receive thread of a discovery socket, between two received messages, as a message received there: Fast DDS's own
// threads, so nothing is delivered to a receiver after Fast DDS closed it (the participant announces itself to its
// discovery sockets every period, so a receive comes at least that often).

#include <fastdds/rtps/transport/ChainingTransport.h>
#include <fastdds/rtps/transport/ChainingTransportDescriptor.h>

#include <memory>

#include "dds/discovery_gate.hpp"

namespace lb::ddsl {

struct GateTransportDescriptor : public eprosima::fastdds::rtps::ChainingTransportDescriptor {
  GateTransportDescriptor(std::shared_ptr<eprosima::fastdds::rtps::TransportDescriptorInterface> low,
                          std::shared_ptr<DiscoveryGate> discovery_gate)
      : ChainingTransportDescriptor(std::move(low)), gate(std::move(discovery_gate)) {}
  eprosima::fastdds::rtps::TransportInterface* create_transport() const override;

  std::shared_ptr<DiscoveryGate> gate;
};

}  // namespace lb::ddsl
