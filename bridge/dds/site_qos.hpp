#pragma once
// What a site's Fast DDS XML profiles may change of the bridge's DDS entities, and what they may
// not because the DDS contract depends on it (README "Site DDS configuration").
//
// Endpoints: a <data_writer> or <data_reader> profile named after the topic (as ROS 2's
// rmw_fastrtps looks them up, e.g. profile_name="rt/demo/saw1/status"), over the file's default
// (is_default_profile="true") one. A site may set timing and liveliness (deadline, latency budget,
// liveliness, lifespan, the reliable protocol's heartbeat and ACK/NACK timing), user data, the
// publish mode (asynchronous, flow controllers) and the history memory policy. Reliability,
// durability, history, resource limits, ownership, partitions, destination order and positive ACKs
// are the contract's (a late joiner gets the current state, every cut and EMCY arrives, writers and
// readers of one topic always match): a profile that sets them is reported and not applied.
// Only what a profile sets differently from Fast DDS's own default is taken, so the bridge's
// choices (a 100 ms heartbeat, for one) stay in force where the site says nothing.

#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>

#include <string>
#include <vector>

namespace lb::ddsl {

// Notes say what was not applied and why ("rt/demo/saw1/status: reliability is the contract's: not applied").
void apply_site_qos(const std::string& topic, eprosima::fastdds::dds::DataWriterQos& qos,
                    std::vector<std::string>& notes);
void apply_site_qos(const std::string& topic, eprosima::fastdds::dds::DataReaderQos& qos,
                    std::vector<std::string>& notes);

}  // namespace lb::ddsl
