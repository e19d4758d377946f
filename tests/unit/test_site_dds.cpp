// The site's DDS configuration: the line file's dds: keys (profiles_file, participant_profile,
// discovery_servers), profiles_dir, and what an XML profile may change of the bridge's QoS and what
// stays the contract's. Nothing here creates a participant: Fast DDS only parses the XML.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fastdds/rtps/attributes/ServerAttributes.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "dds/participant.hpp"
#include "dds/site_qos.hpp"
#include "profiles/line_config.hpp"

namespace fdds = eprosima::fastdds::dds;
using lb::profiles::LineConfig;
using lb::profiles::ProfileRegistry;

namespace {

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "/site_" + std::to_string(::getpid()) + "_" + name;
}

std::string write(const std::string& name, const std::string& text) {
  const auto path = temp_path(name);
  std::ofstream(path) << text;
  return path;
}

const char* kDevices = "buses:\n  - {name: b, interface: 'virtual:site'}\n"
                       "devices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n";

lb::Result<LineConfig> parse(const std::string& head, const ProfileRegistry& registry) {
  const auto path = write("line.yaml", "line: site\n" + head + kDevices);
  return lb::profiles::load_line_config(path, registry);
}

std::string error_of(const std::string& head) {
  const auto registry = ProfileRegistry::builtin();
  auto c = parse(head, registry);
  return c ? std::string("accepted") : c.error().message;
}

// A profile XML with one topic's writer profile that sets what a site may (deadline, heartbeat)
// and what it may not (reliability, durability, history).
const char* kSiteXml = R"(<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <transport_descriptors>
      <transport_descriptor><transport_id>site_udp</transport_id><type>UDPv4</type></transport_descriptor>
    </transport_descriptors>
    <participant profile_name="site_part" is_default_profile="true">
      <rtps>
        <name>site-participant</name>
        <userTransports><transport_id>site_udp</transport_id></userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
      </rtps>
    </participant>
    <data_writer profile_name="rt/site/saw1/status">
      <qos>
        <reliability><kind>BEST_EFFORT</kind></reliability>
        <durability><kind>VOLATILE</kind></durability>
        <deadline><period><sec>2</sec></period></deadline>
      </qos>
      <topic><historyQos><kind>KEEP_LAST</kind><depth>7</depth></historyQos></topic>
      <times><heartbeatPeriod><sec>0</sec><nanosec>250000000</nanosec></heartbeatPeriod></times>
    </data_writer>
    <data_reader profile_name="rt/site/saw1/setpoint">
      <qos><deadline><period><sec>3</sec></period></deadline></qos>
    </data_reader>
  </profiles>
</dds>
)";

TEST(SiteConfig, DdsKeysAreReadAndPathsTakenFromTheLineFile) {
  const auto xml = write("profiles.xml", kSiteXml);
  const auto registry = ProfileRegistry::builtin();
  auto c = parse("dds:\n  localhost_only: false\n  profiles_file: " + std::filesystem::path(xml).filename().string() +
                     "\n  participant_profile: site_part\n  discovery_servers:\n    - {id: 0, address: 10.1.2.3}\n"
                     "    - {id: 7, address: 127.0.0.1, port: 11900}\n",
                 registry);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->dds.profiles_file, std::filesystem::path(xml).lexically_normal().string());
  EXPECT_EQ(c->dds.participant_profile, "site_part");
  ASSERT_EQ(c->dds.discovery_servers.size(), 2U);
  EXPECT_EQ(c->dds.discovery_servers[0].port, 11811);
  EXPECT_EQ(c->dds.discovery_servers[1].id, 7);
  EXPECT_EQ(c->dds.discovery_servers[1].port, 11900);
}

TEST(SiteConfig, BadDdsKeysAreRefusedWithTheirPlace) {
  EXPECT_NE(error_of("dds:\n  profiles_file: no-such.xml\n").find("line.yaml:3:18: profiles_file: cannot open"),
            std::string::npos)
      << error_of("dds:\n  profiles_file: no-such.xml\n");
  EXPECT_NE(error_of("dds:\n  discovery_servers: [{id: 0, address: plant-ds}]\n").find("not an IPv4 address"),
            std::string::npos);
  EXPECT_NE(error_of("dds:\n  discovery_servers: [{address: 127.0.0.1}]\n").find("missing required key 'id'"),
            std::string::npos);
  EXPECT_NE(error_of("dds:\n  discovery_servers: [{id: 1, address: 127.0.0.1}, {id: 1, address: 127.0.0.2}]\n")
                .find("given twice"),
            std::string::npos);
  EXPECT_NE(error_of("dds:\n  discovery_servers: []\n").find("empty"), std::string::npos);
  // localhost_only keeps DDS on 127.0.0.1: a server elsewhere could never be reached.
  EXPECT_NE(error_of("dds:\n  discovery_servers: [{id: 0, address: 10.0.0.5}]\n").find("localhost_only"),
            std::string::npos);
  EXPECT_NE(error_of("dds:\n  discovery_server: []\n").find("unknown key 'discovery_server'"), std::string::npos);
}

TEST(SiteConfig, ProfilesDirLoadsFilesOverTheBuiltInOnes) {
  const auto dir = temp_path("profiles.d");
  std::filesystem::remove_all(dir);  // an earlier run under the same pid left its broken.yaml there
  std::filesystem::create_directories(dir);
  // A copy of the built-in saw 3.1 under another version, and one that replaces saw 1.0.
  std::ifstream in(std::string(LB_SOURCE_DIR) + "/config/profiles/cia420-4-saw-3.1.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string v9 = text.str();
  v9.replace(v9.find("version: \"3.1\""), 14, "version: \"9.0\"");
  std::ofstream(dir + "/saw-9.yaml") << v9;
  std::string v10 = text.str();
  v10.replace(v10.find("version: \"3.1\""), 14, "version: \"1.0\"");
  std::ofstream(dir + "/saw-10.yaml") << v10;
  std::ofstream(dir + "/notes.txt") << "not a profile";
  const auto registry = ProfileRegistry::builtin();
  const auto path = write("dir-line.yaml",
                          "line: site\nprofiles_dir: " + std::filesystem::path(dir).filename().string() +
                              "\nbuses:\n  - {name: b, interface: 'virtual:site'}\ndevices:\n"
                              "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '9.0'}\n");
  auto c = lb::profiles::load_line_config(path, registry);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->devices[0].resolved_profile->version, "9.0");
  ASSERT_TRUE(c->profiles);
  ASSERT_EQ(c->warnings.size(), 1U);
  EXPECT_NE(c->warnings[0].find("saw-10.yaml: profile cia420-4@1.0 replaces"), std::string::npos) << c->warnings[0];
  // A copy of the configuration keeps pointing at live profiles.
  const LineConfig copy = *c;
  EXPECT_EQ(copy.devices[0].resolved_profile->device, "saw");

  // Without the key, 9.0 is unknown; a broken profile file is refused with its own place.
  EXPECT_NE(error_of("").find("accepted"), std::string::npos);
  std::ofstream(dir + "/broken.yaml") << "profile: x\nversion: '1'\ndevice: saw\ndevice_type: [1]\nobjects: []\n";
  auto broken = lb::profiles::load_line_config(path, registry);
  ASSERT_FALSE(broken);
  EXPECT_NE(broken.error().message.find("broken.yaml:4:"), std::string::npos) << broken.error().message;
  EXPECT_NE(error_of("profiles_dir: no-such-dir\n").find("line.yaml:2:15: profiles_dir:"), std::string::npos)
      << error_of("profiles_dir: no-such-dir\n");
}

TEST(SiteConfig, HeartbeatTimeoutWithoutMarginIsAWarning) {
  const auto registry = ProfileRegistry::builtin();
  const auto path =
      write("hb-line.yaml",
            "line: site\nbuses:\n  - {name: b, interface: 'virtual:site'}\ndevices:\n"
            "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 120, "
            "heartbeat_producer_ms: 100}\n");
  auto c = lb::profiles::load_line_config(path, registry);
  ASSERT_TRUE(c) << c.error().message;
  ASSERT_EQ(c->warnings.size(), 1U);
  EXPECT_NE(c->warnings[0].find("less than 1.5 x heartbeat_producer_ms"), std::string::npos) << c->warnings[0];
}

// A secured line through discovery servers delivered nothing with Fast DDS 2.9 (measured, README):
// --check and start-up say so at the servers' place; either alone says nothing.
TEST(SiteConfig, SecurityWithDiscoveryServersIsAWarning) {
  const auto registry = ProfileRegistry::builtin();
  const std::string security =
      "  security: {identity_ca: ca.pem, certificate: c.pem, private_key: k.pem, permissions_ca: pca.pem, "
      "governance: g.p7s, permissions: p.p7s}\n";
  const std::string servers = "  discovery_servers: [{id: 0, address: 127.0.0.1, port: 11811}]\n";
  const auto warnings = [&](const std::string& dds) {
    const auto path = write("sec-ds-line.yaml", "line: site\ndds:\n  domain: 3\n" + dds +
                                                    "buses:\n  - {name: b, interface: 'virtual:site'}\ndevices: []\n");
    auto c = lb::profiles::load_line_config(path, registry);
    EXPECT_TRUE(c) << c.error().message;
    return c ? c->warnings : std::vector<std::string>{};
  };
  const auto both = warnings(security + servers);
  ASSERT_EQ(both.size(), 1U);
  EXPECT_NE(both[0].find("sec-ds-line.yaml:5:22: dds.security with discovery servers"), std::string::npos) << both[0];
  EXPECT_TRUE(warnings(security).empty());
  EXPECT_TRUE(warnings(servers).empty());
}

TEST(SiteQos, TopicProfileChangesTimingNeverTheContract) {
  const auto xml = write("qos.xml", kSiteXml);
  lb::ddsl::ParticipantOptions o;
  o.profiles_file = xml;
  ASSERT_TRUE(lb::ddsl::participant_qos(o, nullptr));  // loads the file

  fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
  qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = fdds::TRANSIENT_LOCAL_DURABILITY_QOS;
  qos.history().depth = 1;
  qos.reliable_writer_qos().times.heartbeatPeriod = {0, 100'000'000};
  std::vector<std::string> notes;
  lb::ddsl::apply_site_qos("rt/site/saw1/status", qos, notes);
  EXPECT_EQ(qos.deadline().period.seconds, 2);                                       // the site's
  EXPECT_EQ(qos.reliable_writer_qos().times.heartbeatPeriod.nanosec, 250'000'000U);  // the site's
  EXPECT_EQ(qos.reliability().kind, fdds::RELIABLE_RELIABILITY_QOS);                 // the contract's
  EXPECT_EQ(qos.durability().kind, fdds::TRANSIENT_LOCAL_DURABILITY_QOS);            // the contract's
  EXPECT_EQ(qos.history().depth, 1);                                                 // the contract's
  std::string all;
  for (const auto& n : notes) all += n + "\n";
  EXPECT_NE(all.find("rt/site/saw1/status: reliability is the DDS contract's"), std::string::npos) << all;
  EXPECT_NE(all.find("durability"), std::string::npos) << all;
  EXPECT_NE(all.find("history"), std::string::npos) << all;

  // A topic without a profile keeps the bridge's own choices.
  fdds::DataWriterQos other = fdds::DATAWRITER_QOS_DEFAULT;
  other.reliable_writer_qos().times.heartbeatPeriod = {0, 100'000'000};
  notes.clear();
  lb::ddsl::apply_site_qos("rt/site/saw1/cut", other, notes);
  EXPECT_EQ(other.reliable_writer_qos().times.heartbeatPeriod.nanosec, 100'000'000U);
  EXPECT_TRUE(notes.empty());

  fdds::DataReaderQos reader = fdds::DATAREADER_QOS_DEFAULT;
  lb::ddsl::apply_site_qos("rt/site/saw1/setpoint", reader, notes);
  EXPECT_EQ(reader.deadline().period.seconds, 3);
}

TEST(SiteQos, ParticipantTakesTheProfileAndTheLineFileDecidesDiscoveryAndLocalhost) {
  const auto xml = write("part.xml", kSiteXml);
  lb::ddsl::ParticipantOptions o;
  o.name = "linebridge/site";
  o.profiles_file = xml;
  o.localhost_only = false;
  std::vector<std::string> notes;
  auto qos = lb::ddsl::participant_qos(o, &notes);
  ASSERT_TRUE(qos) << qos.error().message;
  EXPECT_EQ(qos->name().to_string(), "site-participant");  // the site named it
  EXPECT_FALSE(qos->transport().use_builtin_transports);   // the site's transports
  EXPECT_EQ(qos->transport().user_transports.size(), 1U);
  EXPECT_EQ(qos->wire_protocol().builtin.discovery_config.leaseDuration.seconds,
            10);  // the bridge's, the site said nothing
  EXPECT_TRUE(notes.empty());

  // localhost_only overrides the site's transports (and says so); discovery servers make a client.
  o.localhost_only = true;
  o.discovery_servers = {{3, "127.0.0.1", 11999}};
  qos = lb::ddsl::participant_qos(o, &notes);
  ASSERT_TRUE(qos);
  ASSERT_EQ(notes.size(), 1U);
  EXPECT_NE(notes[0].find("localhost_only"), std::string::npos);
  EXPECT_EQ(qos->transport().user_transports.size(), 1U);  // UDP on 127.0.0.1 only (no shared memory by default)
  const auto& d = qos->wire_protocol().builtin.discovery_config;
  EXPECT_EQ(d.discoveryProtocol, eprosima::fastrtps::rtps::DiscoveryProtocol_t::CLIENT);
  ASSERT_EQ(d.m_DiscoveryServers.size(), 1U);
  eprosima::fastrtps::rtps::GuidPrefix_t prefix;
  eprosima::fastdds::rtps::get_server_client_default_guidPrefix(3, prefix);
  EXPECT_EQ(d.m_DiscoveryServers.front().guidPrefix, prefix);  // fast-discovery-server -i 3
  EXPECT_EQ(d.m_DiscoveryServers.front().metatrafficUnicastLocatorList.begin()->port, 11999U);
  EXPECT_TRUE(qos->wire_protocol().builtin.initialPeersList.empty());
  o.see_all_endpoints = true;
  EXPECT_EQ(lb::ddsl::participant_qos(o, nullptr)->wire_protocol().builtin.discovery_config.discoveryProtocol,
            eprosima::fastrtps::rtps::DiscoveryProtocol_t::SUPER_CLIENT);

  o.shared_memory = true;
  EXPECT_EQ(lb::ddsl::participant_qos(o, nullptr)->transport().user_transports.size(), 2U);  // and shared memory

  // Without a profile's transports, not localhost-only: UDP on every interface, no shared memory.
  lb::ddsl::ParticipantOptions plain;
  plain.localhost_only = false;
  auto udp = lb::ddsl::participant_qos(plain, nullptr);
  ASSERT_TRUE(udp);
  EXPECT_FALSE(udp->transport().use_builtin_transports);
  ASSERT_EQ(udp->transport().user_transports.size(), 1U);
  EXPECT_TRUE(udp->wire_protocol().builtin.initialPeersList.empty());

  o.participant_profile = "no_such_profile";
  auto missing = lb::ddsl::participant_qos(o, nullptr);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("no participant profile 'no_such_profile'"), std::string::npos);
}

TEST(SiteQos, BrokenXmlIsRefusedWithItsLine) {
  const auto xml = write("broken.xml",
                         "<?xml version=\"1.0\"?>\n<dds>\n<profiles>\n<participant profile_name=\"x\">\n</dds>\n");
  lb::ddsl::ParticipantOptions o;
  o.profiles_file = xml;
  auto qos = lb::ddsl::participant_qos(o, nullptr);
  ASSERT_FALSE(qos);
  EXPECT_NE(qos.error().message.find(xml + ":"), std::string::npos) << qos.error().message;
  EXPECT_NE(qos.error().message.find("XML error"), std::string::npos) << qos.error().message;
}

}  // namespace
