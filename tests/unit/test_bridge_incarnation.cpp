// A request names the run of the bridge it is for (dds/incarnation.hpp): the rule itself, and
// ServiceServer/ServiceClient in one process, where a server "restarts" by being replaced with a
// new participant while the first still holds the request unanswered (killed before answering).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <future>
#include <mutex>
#include <set>
#include <vector>

#include "dds/incarnation.hpp"
#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/routing/bridge_runs.hpp"
#include "gateways/routing/management_services.hpp"
#include "msgs/commonPubSubTypes.h"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using lb::ddsl::Incarnation;
using lb::ddsl::kAnyIncarnation;

TEST(BridgeIncarnation, DrawnAtRandomAndNeverAny) {
  std::set<Incarnation> drawn;
  for (int i = 0; i < 1000; ++i) {
    const auto x = lb::ddsl::draw_incarnation();
    EXPECT_NE(x, kAnyIncarnation);
    drawn.insert(x);
  }
  EXPECT_EQ(drawn.size(), 1000u) << "64 random bits do not repeat in 1000 draws";
}

TEST(BridgeIncarnation, ARequestRunsOnlyOnTheRunItNamesOrOnAnyWhenItNamesNone) {
  EXPECT_TRUE(lb::ddsl::meant_for(7, 7));
  EXPECT_TRUE(lb::ddsl::meant_for(kAnyIncarnation, 7)) << "an old client's request runs";
  EXPECT_FALSE(lb::ddsl::meant_for(7, 8)) << "meant for an earlier run";
  // The reply names who answered: from another run than the one named, and refused so, it is the
  // refusal; a stop runs on any run, and its own answer (success or not) is no such refusal.
  const std::string refusal(lb::ddsl::kRestartedRefusal);
  EXPECT_TRUE(lb::ddsl::refused_as_restarted(7, 8, false, refusal));
  EXPECT_FALSE(lb::ddsl::refused_as_restarted(7, 7, false, refusal));
  EXPECT_FALSE(lb::ddsl::refused_as_restarted(kAnyIncarnation, 8, false, refusal));
  EXPECT_FALSE(lb::ddsl::refused_as_restarted(7, 8, true, "")) << "a stop that ran on the next run";
  EXPECT_FALSE(lb::ddsl::refused_as_restarted(7, 8, false, "saw1 is offline")) << "a stop refused for its own reason";
}

namespace {

using Server = lb::ddsl::ServiceServer<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>;
using Client = lb::ddsl::ServiceClient<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>;
constexpr const char* kLine = "inc";

// One run of a bridge: a participant with the command service and diagnostics naming its run.
struct BridgeRun {
  std::unique_ptr<lb::ddsl::Participant> dds;
  lb::ddsl::Writer<msg::DiagnosticsPubSubType> diagnostics;

  // answer: whether the handler answers (the first run is killed before it does).
  // stops: the server's Stops (which requests run on any run).
  BridgeRun(std::uint32_t domain, bool answer, std::atomic<int>& runs, std::promise<Incarnation>* named = nullptr,
            Server::Stops stops = {}) {
    auto p = lb::ddsl::Participant::create({domain, true, "run"});
    if (!p) throw std::runtime_error(p.error().message);
    dds = std::move(*p);
    auto served = Server::serve(
        *dds, lb::ddsl::line_service_path(kLine, "command"),
        [answer, &runs, named](const srv::Command_Request& req, Server::Responder respond) {
          if (++runs == 1 && named != nullptr) named->set_value(req.bridge_incarnation());
          if (!answer) return;
          srv::Command_Response done;
          done.success(true);
          respond(done);
        },
        std::move(stops));
    if (!served) throw std::runtime_error(served.error().message);
    auto w = dds->writer<msg::DiagnosticsPubSubType>(lb::ddsl::topic_name(kLine, "bridge", "diagnostics"),
                                                     lb::ddsl::QosKind::state);
    if (!w) throw std::runtime_error(w.error().message);
    diagnostics = *w;
    msg::Diagnostics d;
    d.line(kLine);
    d.bridge_incarnation(dds->incarnation());
    diagnostics.write(d);  // transient-local: a client matched later still gets it
  }
};

}  // namespace

TEST(BridgeIncarnation, ARepeatThatReachesARestartedServerIsRefusedUnrunAndTheNextRequestRuns) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  constexpr std::uint32_t kDomain = 41;
  auto client_dds = lb::ddsl::Participant::create({kDomain, true, "client"});
  ASSERT_TRUE(client_dds) << client_dds.error().message;
  auto client = Client::create(**client_dds, lb::ddsl::line_service_path(kLine, "command"),
                               lb::gateways::bridge_runs(kLine));
  ASSERT_TRUE(client) << client.error().message;

  std::atomic<int> first_runs{0}, second_runs{0};
  std::promise<Incarnation> named;
  auto first = std::make_unique<BridgeRun>(kDomain, false, first_runs, &named);
  const Incarnation first_run = first->dds->incarnation();

  srv::Command_Request cut;
  cut.device("saw1");
  cut.command("manual_cut");
  auto asked = std::async(std::launch::async, [&] { return (*client)->ask(cut, 30s); });
  auto named_run = named.get_future();
  ASSERT_EQ(named_run.wait_for(20s), std::future_status::ready) << "the request never reached the first run";
  EXPECT_EQ(named_run.get(), first_run) << "the client names the run it heard of before its first send";

  first.reset();  // killed before it answered
  BridgeRun second(kDomain, true, second_runs);
  ASSERT_NE(second.dds->incarnation(), first_run);

  const auto answer = asked.get();  // the client asks again every second: the second run gets a repeat
  ASSERT_TRUE(answer) << answer.error().message;
  EXPECT_TRUE(answer->bridge_restarted());
  EXPECT_FALSE(answer->reply.success());
  EXPECT_EQ(answer->reply.message(), std::string(lb::ddsl::kRestartedRefusal));
  EXPECT_EQ(answer->reply.bridge_incarnation(), second.dds->incarnation());
  EXPECT_EQ(answer->asked_of, first_run);
  EXPECT_EQ(first_runs, 1);
  EXPECT_EQ(second_runs, 0) << "the repeat ran on the restarted server";

  // The client has heard of the second run now (its refusal, its diagnostics): a new request runs.
  const auto next = (*client)->ask(cut, 20s);
  ASSERT_TRUE(next) << next.error().message;
  EXPECT_TRUE(next->reply.success()) << next->reply.message();
  EXPECT_FALSE(next->bridge_restarted());
  EXPECT_EQ(next->asked_of, second.dds->incarnation());
  EXPECT_EQ(second_runs, 1);
}

// A stop is never refused while the device is heard: a repeat of one that reaches a restarted
// server runs there (stopping twice is still stopped), answered as its own, not as the refusal;
// the same server still refuses any other request that names the run before it.
TEST(BridgeIncarnation, AStopRepeatedToARestartedServerRunsThereAndOtherRequestsAreStillRefused) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  constexpr std::uint32_t kDomain = 42;
  auto client_dds = lb::ddsl::Participant::create({kDomain, true, "client"});
  ASSERT_TRUE(client_dds) << client_dds.error().message;
  auto client = Client::create(**client_dds, lb::ddsl::line_service_path(kLine, "command"),
                               lb::gateways::bridge_runs(kLine));
  ASSERT_TRUE(client) << client.error().message;
  const auto stops = [](const srv::Command_Request& r) { return r.command() == "stop_immediately"; };

  std::atomic<int> first_runs{0}, second_runs{0};
  std::promise<Incarnation> named;
  auto first = std::make_unique<BridgeRun>(kDomain, false, first_runs, &named, stops);
  const Incarnation first_run = first->dds->incarnation();

  srv::Command_Request stop;
  stop.device("saw1");
  stop.command("stop_immediately");
  auto asked = std::async(std::launch::async, [&] { return (*client)->ask(stop, 30s); });
  auto named_run = named.get_future();
  ASSERT_EQ(named_run.wait_for(20s), std::future_status::ready) << "the stop never reached the first run";
  EXPECT_EQ(named_run.get(), first_run);

  first.reset();  // killed before it answered
  BridgeRun second(kDomain, true, second_runs, nullptr, stops);

  const auto answer = asked.get();  // the client's repeat names the first run
  ASSERT_TRUE(answer) << answer.error().message;
  EXPECT_EQ(answer->asked_of, first_run);
  EXPECT_TRUE(answer->reply.success()) << "the repeated stop was refused: " << answer->reply.message();
  EXPECT_FALSE(answer->bridge_restarted());
  EXPECT_EQ(answer->reply.bridge_incarnation(), second.dds->incarnation());
  EXPECT_EQ(second_runs, 1) << "the repeated stop did not run on the restarted server";

  // Any other request naming the run before is refused unrun, as ever.
  srv::Command_Request cut;
  cut.device("saw1");
  cut.command("manual_cut");
  cut.bridge_incarnation(first_run);
  const auto refused = (*client)->ask(cut, 20s);
  ASSERT_TRUE(refused) << refused.error().message;
  EXPECT_TRUE(refused->bridge_restarted());
  EXPECT_EQ(refused->reply.message(), std::string(lb::ddsl::kRestartedRefusal));
  EXPECT_EQ(second_runs, 1) << "a request meant for the run before ran";
}

// The line-wide nmt service's rule (ManagementServices::stops as the server's Stops): a reset
// node or reset communication naming another run is refused unrun with the restart text, as a
// start is; a stop and enter pre-operational naming it run. The handler stands for the bus: it
// is what would send the NMT frame.
TEST(BridgeIncarnation, AResetNamingAnotherRunIsRefusedUnrunAndAStopRuns) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  using NmtServer = lb::ddsl::ServiceServer<srv::Nmt_RequestPubSubType, srv::Nmt_ResponsePubSubType>;
  using NmtClient = lb::ddsl::ServiceClient<srv::Nmt_RequestPubSubType, srv::Nmt_ResponsePubSubType>;
  constexpr std::uint32_t kDomain = 43;
  auto server_dds = lb::ddsl::Participant::create({kDomain, true, "run"});
  ASSERT_TRUE(server_dds) << server_dds.error().message;
  std::mutex m;
  std::vector<srv::NmtCommand> sent;  // what reached the "bus"
  auto served = NmtServer::serve(
      **server_dds, lb::ddsl::line_service_path(kLine, "nmt"),
      [&](const srv::Nmt_Request& req, NmtServer::Responder respond) {
        {
          std::lock_guard lock(m);
          sent.push_back(req.command());
        }
        srv::Nmt_Response done;
        done.success(true);
        respond(done);
      },
      [](const srv::Nmt_Request& r) { return lb::gateways::ManagementServices::stops(r); });
  ASSERT_TRUE(served) << served.error().message;
  const Incarnation own = (*server_dds)->incarnation();
  const Incarnation before = own + 1 == kAnyIncarnation ? own + 2 : own + 1;  // a run that is not this one

  auto client_dds = lb::ddsl::Participant::create({kDomain, true, "client"});
  ASSERT_TRUE(client_dds) << client_dds.error().message;
  auto client = NmtClient::create(**client_dds, lb::ddsl::line_service_path(kLine, "nmt"));
  ASSERT_TRUE(client) << client.error().message;
  const auto ask = [&](srv::NmtCommand c) {
    srv::Nmt_Request r;
    r.device("saw1");
    r.command(c);
    r.bridge_incarnation(before);
    return (*client)->ask(r, 20s);
  };
  const auto sent_now = [&] {
    std::lock_guard lock(m);
    return sent;
  };

  for (const auto c : {srv::NMT_RESET_NODE, srv::NMT_RESET_COMMUNICATION, srv::NMT_START}) {
    const auto answer = ask(c);
    ASSERT_TRUE(answer) << answer.error().message;
    EXPECT_FALSE(answer->reply.success()) << "command " << static_cast<int>(c) << " naming another run ran";
    EXPECT_TRUE(answer->bridge_restarted());
    EXPECT_EQ(answer->reply.message(), std::string(lb::ddsl::kRestartedRefusal));
    EXPECT_EQ(answer->reply.bridge_incarnation(), own);
  }
  EXPECT_TRUE(sent_now().empty()) << "a request naming another run reached the bus";
  for (const auto c : {srv::NMT_STOP, srv::NMT_ENTER_PRE_OPERATIONAL}) {
    const auto answer = ask(c);
    ASSERT_TRUE(answer) << answer.error().message;
    EXPECT_TRUE(answer->reply.success()) << "a stop naming another run was refused: " << answer->reply.message();
    EXPECT_FALSE(answer->bridge_restarted());
  }
  EXPECT_EQ(sent_now(), (std::vector<srv::NmtCommand>{srv::NMT_STOP, srv::NMT_ENTER_PRE_OPERATIONAL}));
}
