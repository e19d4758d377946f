// The line-wide management services' routing: a request naming no device, or one the line does not
// have, or asking a device without momentary commands for one, is refused at once with the reason
// and the names that would work, without reaching any device. (Routing to a device's handler is
// tested end to end in the integration tests, with the real bridge.)
#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "gateways/routing/management_services.hpp"

namespace srv = linebridge_msgs::srv;
using lb::gateways::ManagementServices;

namespace {

template <class Reply>
struct Answer {
  std::optional<Reply> reply;
  int calls = 0;
  lb::ddsl::Respond<Reply> respond() {
    return [this](const Reply& r) {
      reply = r;
      ++calls;
    };
  }
  // The reason of the one refusal the request got, or what came instead (so a test fails with it).
  std::string refusal() const {
    if (calls != 1) return "<" + std::to_string(calls) + " replies>";
    if (reply->success()) return "<accepted: " + reply->message() + ">";
    return reply->message();
  }
};

}  // namespace

// No handlers (null): every request here must be refused before one would be needed.
TEST(ManagementServices, UnknownDeviceIsRefusedNamingItAndTheLinesDevices) {
  const ManagementServices router("demo", {{"saw1", "saw, cia420-4@3.1", nullptr, nullptr},
                                           {"puller1", "puller, cia420-2@1.0", nullptr, nullptr},
                                           {"feeders", "feeder, cia414-2@1.1", nullptr, nullptr}});
  Answer<srv::SdoRead_Response> read;
  srv::SdoRead_Request rq;
  rq.device("saw9");
  rq.index(0x1008);
  rq.data_type("VISIBLE_STRING");
  router.sdo_read(rq, read.respond());
  ASSERT_EQ(read.calls, 1);
  EXPECT_FALSE(read.reply->success());
  EXPECT_EQ(read.reply->abort_code(), 0u);
  EXPECT_EQ(read.reply->message(), "no device 'saw9' on line demo (devices: saw1, puller1, feeders)");

  // Every service routes the same way.
  Answer<srv::Nmt_Response> nmt;
  srv::Nmt_Request nq;
  nq.device("Saw1");  // names are case-sensitive, as in topic names
  nq.command(srv::NMT_RESET_NODE);
  router.nmt(nq, nmt.respond());
  EXPECT_EQ(nmt.refusal(), "no device 'Saw1' on line demo (devices: saw1, puller1, feeders)");

  Answer<srv::SdoWrite_Response> write;
  srv::SdoWrite_Request wq;
  wq.device("ghost");
  router.sdo_write(wq, write.respond());
  EXPECT_NE(write.refusal().find("no device 'ghost'"), std::string::npos) << write.refusal();

  Answer<srv::GetParameter_Response> get;
  srv::GetParameter_Request gq;
  gq.device("ghost");
  gq.parameter("saw_cut_depth");
  router.get_parameter(gq, get.respond());
  EXPECT_NE(get.refusal().find("no device 'ghost'"), std::string::npos) << get.refusal();

  Answer<srv::SetParameter_Response> set;
  srv::SetParameter_Request sq;
  sq.device("ghost");
  sq.parameter("saw_cut_depth");
  sq.value(0.01);
  router.set_parameter(sq, set.respond());
  EXPECT_NE(set.refusal().find("no device 'ghost'"), std::string::npos) << set.refusal();

  Answer<srv::Command_Response> press;
  srv::Command_Request cq;
  cq.device("ghost");
  cq.command("manual_cut");
  router.command(cq, press.respond());
  EXPECT_NE(press.refusal().find("no device 'ghost'"), std::string::npos) << press.refusal();
}

TEST(ManagementServices, RequestWithoutDeviceIsRefused) {
  const ManagementServices router("demo", {{"saw1", "saw, cia420-4@3.1", nullptr, nullptr}});
  Answer<srv::Nmt_Response> nmt;
  srv::Nmt_Request nq;  // device left empty, as a client of the per-device services would send it
  nq.command(srv::NMT_START);
  router.nmt(nq, nmt.respond());
  EXPECT_EQ(nmt.refusal(), "the request names no device (field 'device'; line demo: devices: saw1)");
}

TEST(ManagementServices, DeviceWithoutMomentaryCommandsIsRefused) {
  // Only the gateway knows its commands: a null CommandService is a device type without any.
  const ManagementServices feeders_only("weave", {{"feeders", "feeder, cia414-2@1.1", nullptr, nullptr}});
  Answer<srv::Command_Response> press;
  srv::Command_Request cq;
  cq.device("feeders");
  cq.command("start");
  feeders_only.command(cq, press.respond());
  EXPECT_EQ(press.refusal(),
            "feeders (feeder, cia414-2@1.1) has no momentary commands (no device of line weave has any)");

  const ManagementServices empty("void", {});
  Answer<srv::Command_Response> none;
  empty.command(cq, none.respond());
  EXPECT_EQ(none.refusal(), "no device 'feeders' on line void (it has none)");
}

// Which NMT requests run whatever run of the bridge they name (a stop is never refused while the
// device is heard): stop and enter pre-operational only. A reset releases any hold and its boot
// ends in NMT start, so a repeat of one naming an earlier run must be refused as a start is.
TEST(ManagementServices, OnlyStopAndPreOperationalRunOnAnyRun) {
  const auto stops = [](srv::NmtCommand c) {
    srv::Nmt_Request r;
    r.device("saw1");
    r.command(c);
    return ManagementServices::stops(r);
  };
  EXPECT_TRUE(stops(srv::NMT_STOP));
  EXPECT_TRUE(stops(srv::NMT_ENTER_PRE_OPERATIONAL));
  EXPECT_FALSE(stops(srv::NMT_START));
  EXPECT_FALSE(stops(srv::NMT_RESET_NODE)) << "a reset ends in NMT start: not a stop";
  EXPECT_FALSE(stops(srv::NMT_RESET_COMMUNICATION)) << "a reset ends in NMT start: not a stop";
}
