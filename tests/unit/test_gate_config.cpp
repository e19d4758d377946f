// The discovery gate's configuration (issue 41 point 1): the line file's
// dds.max_pending_participants reaches the bridge's and every client's participant, the key that
// ended the DDS process past a number of participants is gone with a warning, and the participant's
// transports sit behind the gate (shared memory and discovery servers aside). No participant is
// created here; the gate in a real participant: tests/integration/test_discovery_flood.cpp.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>

#include <fstream>
#include <memory>
#include <string>

#include "app/dds_options.hpp"
#include "dds/gate_transport.hpp"
#include "dds/participant.hpp"
#include "profiles/line_config.hpp"

using lb::profiles::LineConfig;
using lb::profiles::ProfileRegistry;

namespace {

const char* kRest = "buses:\n  - {name: b, interface: 'virtual:gate'}\n"
                    "devices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n";

lb::Result<LineConfig> parse(const std::string& dds) {
  const auto path = ::testing::TempDir() + "/gate_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(path) << "line: gate\ndds:\n" << dds << kRest;
  static const auto registry = ProfileRegistry::builtin();
  return lb::profiles::load_line_config(path, registry);
}

TEST(GateConfig, MaxPendingParticipantsReachesTheBridgeAndEveryClient) {
  auto line = parse("  domain: 7\n  max_pending_participants: 16\n");
  ASSERT_TRUE(line) << line.error().message;
  EXPECT_EQ(lb::app::bridge_participant_options(*line).gate.pending, 16);
  auto client = lb::app::client_participant_options(*line, "cli", "");
  ASSERT_TRUE(client) << client.error().message;
  EXPECT_EQ(client->gate.pending, 16);
  auto fallback = parse("  domain: 7\n");
  ASSERT_TRUE(fallback);
  EXPECT_EQ(fallback->dds.max_pending_participants, 32);
  EXPECT_TRUE(fallback->warnings.empty());
}

TEST(GateConfig, MaxPendingParticipantsOutOfRangeIsRefusedWithItsPlace) {
  for (const char* v : {"0", "65", "many"}) {
    auto line = parse(std::string("  domain: 7\n  max_pending_participants: ") + v + "\n");
    ASSERT_FALSE(line) << v;
    EXPECT_NE(line.error().message.find("max_pending_participants"), std::string::npos) << line.error().message;
  }
}

TEST(GateConfig, TheOldMaxRemoteParticipantsIsIgnoredWithAWarningNamingItsReplacement) {
  auto line = parse("  domain: 7\n  max_remote_participants: 32\n");
  ASSERT_TRUE(line) << line.error().message;
  ASSERT_EQ(line->warnings.size(), 1U);
  EXPECT_NE(line->warnings[0].find("max_remote_participants is no longer used"), std::string::npos)
      << line->warnings[0];
  EXPECT_NE(line->warnings[0].find("dds.max_pending_participants"), std::string::npos) << line->warnings[0];
}

TEST(GateConfig, EveryTransportButSharedMemorySitsBehindTheGate) {
  lb::ddsl::ParticipantOptions options;
  options.shared_memory = true;
  auto gate = std::make_shared<lb::ddsl::DiscoveryGate>(lb::ddsl::DiscoveryGate::Proof::traffic,
                                                        lb::ddsl::GateLimits{});
  auto qos = lb::ddsl::participant_qos(options, nullptr, gate);
  ASSERT_TRUE(qos) << qos.error().message;
  const auto& transports = qos->transport().user_transports;
  ASSERT_EQ(transports.size(), 2U);
  const auto gated = std::dynamic_pointer_cast<lb::ddsl::GateTransportDescriptor>(transports[0]);
  ASSERT_TRUE(gated) << "UDP is not behind the gate";
  EXPECT_EQ(gated->gate, gate);
  const auto udp = std::dynamic_pointer_cast<eprosima::fastdds::rtps::UDPv4TransportDescriptor>(
      gated->low_level_descriptor);
  ASSERT_TRUE(udp);
  ASSERT_EQ(udp->interfaceWhiteList.size(), 1U);  // localhost_only: 127.0.0.1 still
  EXPECT_EQ(udp->interfaceWhiteList[0], "127.0.0.1");
  EXPECT_TRUE(std::dynamic_pointer_cast<eprosima::fastdds::rtps::SharedMemTransportDescriptor>(transports[1]));
  // Without a gate (a tool that drives Fast DDS itself): the transports as they were.
  auto plain = lb::ddsl::participant_qos(options, nullptr);
  ASSERT_TRUE(plain);
  EXPECT_FALSE(std::dynamic_pointer_cast<lb::ddsl::GateTransportDescriptor>(plain->transport().user_transports[0]));
}

TEST(GateConfig, ADiscoveryServersClientHasNoGate) {
  // Its announcement reader takes data from its servers only (Fast DDS's CLIENT): nothing to gate,
  // and the servers relay other participants' announcements under their own prefix.
  lb::ddsl::ParticipantOptions options;
  options.discovery_servers.push_back({0, "127.0.0.1", 11811});
  auto gate = std::make_shared<lb::ddsl::DiscoveryGate>(lb::ddsl::DiscoveryGate::Proof::traffic,
                                                        lb::ddsl::GateLimits{});
  std::vector<std::string> notes;
  auto qos = lb::ddsl::participant_qos(options, &notes, gate);
  ASSERT_TRUE(qos) << qos.error().message;
  for (const auto& t : qos->transport().user_transports)
    EXPECT_FALSE(std::dynamic_pointer_cast<lb::ddsl::GateTransportDescriptor>(t));
}

}  // namespace
