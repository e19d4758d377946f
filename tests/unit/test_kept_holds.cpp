// Holds kept across restarts of the bridge: the holds file (<state_dir>/<line>.holds) as the store
// writes and reads it, and HoldKeeper, which records who holds a device whenever its node's hold
// changes and puts a kept hold back on the node at start-up. The expected file text is written by
// hand from the format (gateways/persistence/kept_holds.hpp).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>

#include "canopen/bus_loop.hpp"
#include "canopen/remote_node.hpp"
#include "gateways/persistence/hold_keeper.hpp"
#include "gateways/persistence/kept_holds.hpp"
#include "gateways/persistence/set_value_store.hpp"
#include "support/scratch_files.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;
using lb::gateways::HoldKeeper;
using lb::gateways::KeptHold;
using lb::gateways::SetValueStore;

namespace {

std::string temp_dir(const std::string& name) { return lb::test::fresh_dir("holds-" + name); }
const KeptHold::Key kSaw{"extrusion", 5, "cia420-4@3.1"};
const KeptHold::Key kPuller{"extrusion", 3, "cia420-2@1.0"};
constexpr std::int64_t kSince = 1700000000;  // 2023-11-14 22:13:20 UTC

std::unique_ptr<SetValueStore> open_store(const std::string& dir, bool restore = true) {
  auto store = SetValueStore::open(dir, "line", restore);
  if (!store) throw std::runtime_error(store.error().message);
  return std::move(*store);
}

}  // namespace

TEST(SetValueStoreHolds, WrittenWithWhoHoldsWhatSinceWhenAndReadBack) {
  const auto dir = temp_dir("roundtrip");
  {
    auto store = open_store(dir);
    EXPECT_TRUE(store->restored_holds().empty());
    EXPECT_EQ(store->holds_path(), dir + "/line.holds");
    store->save_hold(kSaw, KeptHold{KeptHold::Holder::operator_stop, kSince, ""});
    store->save_hold(kPuller,
                     KeptHold{KeptHold::Holder::line_stop, kSince + 1, "mandatory device saw1 its heartbeat was lost"});
  }  // written at the stop at the latest
  const auto text = lb::test::read_text(dir + "/line.holds");
  EXPECT_NE(text.find("\nformat 1\n"
                      "extrusion 3 cia420-2@1.0 line-stop 1700000001 mandatory device saw1 its heartbeat was lost\n"
                      "extrusion 5 cia420-4@3.1 operator-stop 1700000000 -\n"),
            std::string::npos)
      << text;
  {
    auto again = open_store(dir);
    EXPECT_EQ(again->holds_problem(), "");
    const auto& held = again->restored_holds();
    ASSERT_EQ(held.size(), 2u);
    EXPECT_EQ(held.at(kSaw), (KeptHold{KeptHold::Holder::operator_stop, kSince, ""}));
    EXPECT_EQ(held.at(kPuller).holder, KeptHold::Holder::line_stop);
    EXPECT_EQ(held.at(kPuller).reason, "mandatory device saw1 its heartbeat was lost");
    EXPECT_EQ(lb::gateways::describe(held.at(kSaw)),
              "held stopped by an operator's nmt stop since 2023-11-14 22:13:20 UTC");
    // Released: gone from the file.
    again->save_hold(kSaw, std::nullopt);
    again->save_hold(kPuller, KeptHold{KeptHold::Holder::operator_pre_operational, kSince, ""});
  }
  const auto after = lb::test::read_text(dir + "/line.holds");
  EXPECT_EQ(after.find("extrusion 5 "), std::string::npos) << after;
  EXPECT_NE(after.find("extrusion 3 cia420-2@1.0 operator-pre-operational 1700000000 -\n"), std::string::npos) << after;
  // restore_set_values: false starts devices from zero, but a hold is no value: it comes back.
  auto no_values = open_store(dir, false);
  EXPECT_EQ(no_values->restored_holds().size(), 1u);
}

TEST(SetValueStoreHolds, AnotherFormatRestoresNothingAndJunkLinesAreSaid) {
  const auto dir = temp_dir("format");
  std::ofstream(dir + "/line.holds") << "format 2\nextrusion 5 cia420-4@3.1 operator-stop 1700000000 -\n";
  {
    auto store = open_store(dir);
    EXPECT_TRUE(store->restored_holds().empty());
    EXPECT_NE(store->holds_problem().find("not this bridge's hold format (1)"), std::string::npos)
        << store->holds_problem();
  }
  std::ofstream(dir + "/line.holds", std::ios::trunc) << "extrusion 5 cia420-4@3.1 operator-stop 1700000000 -\n";
  {
    auto store = open_store(dir);
    EXPECT_TRUE(store->restored_holds().empty());
    EXPECT_NE(store->holds_problem().find("no 'format 1' line"), std::string::npos) << store->holds_problem();
  }
  std::ofstream(dir + "/line.holds", std::ios::trunc)
      << "format 1\nextrusion 5 cia420-4@3.1 operator-stop 1700000000 -\n"
      << "extrusion 200 cia420-4@3.1 operator-stop 1700000000 -\n"  // no such node-ID
      << "extrusion 6 cia420-4@3.1 someone-else 1700000000 -\n"
      << "extrusion 7 cia420-4@3.1 line-stop yesterday -\n";
  auto store = open_store(dir);
  EXPECT_EQ(store->restored_holds().size(), 1u);
  EXPECT_TRUE(store->restored_holds().contains(kSaw));
  EXPECT_NE(store->holds_problem().find("3 line(s) were not hold lines"), std::string::npos) << store->holds_problem();
}

// A holds file that cannot be used costs the holds, never the store (the set values are kept),
// and a link planted there is never followed: the first change replaces it with a file.
TEST(SetValueStoreHolds, ALinkIsRefusedNotFollowed) {
  const auto dir = temp_dir("link");
  const auto target = dir + "/elsewhere";
  std::ofstream(target) << "format 1\nextrusion 5 cia420-4@3.1 operator-stop 1700000000 -\n";
  ASSERT_EQ(::symlink(target.c_str(), (dir + "/line.holds").c_str()), 0);
  {
    auto store = open_store(dir);
    EXPECT_TRUE(store->restored_holds().empty());
    EXPECT_NE(store->holds_problem().find("symbolic link"), std::string::npos) << store->holds_problem();
    store->save_hold(kPuller, KeptHold{KeptHold::Holder::operator_stop, kSince, ""});
  }
  EXPECT_EQ(lb::test::read_text(target), "format 1\nextrusion 5 cia420-4@3.1 operator-stop 1700000000 -\n");
  struct stat st {};
  ASSERT_EQ(::lstat((dir + "/line.holds").c_str(), &st), 0);
  EXPECT_TRUE(S_ISREG(st.st_mode));
  EXPECT_NE(lb::test::read_text(dir + "/line.holds").find("extrusion 3 "), std::string::npos);
}

namespace {

class SetValueStoreHoldKeeper : public lb::test::LoopOnOwnBus {
 protected:
  SetValueStoreHoldKeeper() : LoopOnOwnBus("holdkeeper") {}

  template <class F>
  auto on_loop(F f) {
    std::promise<decltype(f())> p;
    auto fut = p.get_future();
    loop_->post([&] {
      if constexpr (std::is_void_v<decltype(f())>) {
        f();
        p.set_value();
      } else {
        p.set_value(f());
      }
    });
    return fut.get();
  }
  // The keeper settles in a task posted after the change: one more round trip sees it settled.
  std::optional<KeptHold> kept(const HoldKeeper& keeper) {
    on_loop([] {});
    return on_loop([&] { return keeper.kept(); });
  }
};

}  // namespace

// At start-up a kept hold goes back on the node (the boot then puts the device back in that state
// instead of starting it), and diagnostics say it is from before the restart. An operator's stop
// after that is the operator's own (a new record); a line's stop is the line's with its reason;
// the line's wait for a mandatory device is never kept; a start releases it, on disk too.
TEST_F(SetValueStoreHoldKeeper, PutsAKeptHoldBackAndRecordsWhoHoldsTheDevice) {
  const auto dir = temp_dir("keeper");
  std::ofstream(dir + "/line.holds") << "format 1\nextrusion 5 cia420-4@3.1 operator-pre-operational 1700000000 -\n";
  auto store = open_store(dir);
  co::RemoteNode node(*loop_, 5, 300ms, true);
  HoldKeeper keeper(*loop_, node, *store, kSaw, "saw1");
  HoldKeeper::LineHold line;  // what the line holds the device in, as MandatoryDevices would say
  keeper.set_line_view([&line] { return line; });

  const auto restored = keeper.restore();
  ASSERT_TRUE(restored);
  EXPECT_EQ(restored->holder, KeptHold::Holder::operator_pre_operational);
  EXPECT_EQ(node.operator_hold(), co::NmtCommand::enter_pre_operational);
  loop_->start();
  EXPECT_EQ(kept(keeper), restored) << "the restored hold was recorded anew";
  EXPECT_EQ(on_loop([&] { return keeper.note(); }),
            "held pre-operational by an operator's nmt pre-operational since 2023-11-14 22:13:20 UTC, kept from "
            "before the bridge restarted");

  // An operator's stop (NodeStateMachine::operator_command, then DeviceServices' listener).
  on_loop([&] {
    node.hold(co::NmtCommand::stop);
    keeper.operator_command(co::NmtCommand::stop);
  });
  auto now = kept(keeper);
  ASSERT_TRUE(now);
  EXPECT_EQ(now->holder, KeptHold::Holder::operator_stop);
  EXPECT_GT(now->since_s, kSince);
  EXPECT_EQ(on_loop([&] { return keeper.note(); }).find("before the bridge restarted"), std::string::npos);

  // Released by an operator's start, then held by the line (stop_others), then by its wait.
  on_loop([&] { node.release_hold(); });
  EXPECT_FALSE(kept(keeper));
  on_loop([&] {
    line = {HoldKeeper::LineHold::Kind::stopped, "mandatory device saw2 its heartbeat was lost"};
    node.hold(co::NmtCommand::stop);
  });
  now = kept(keeper);
  ASSERT_TRUE(now);
  EXPECT_EQ(now->holder, KeptHold::Holder::line_stop);
  EXPECT_EQ(now->reason, "mandatory device saw2 its heartbeat was lost");
  on_loop([&] {
    line = {};
    node.release_hold();
  });
  EXPECT_FALSE(kept(keeper));
  on_loop([&] {
    line = {HoldKeeper::LineHold::Kind::waiting, "waiting for mandatory device saw2"};
    node.hold(co::NmtCommand::enter_pre_operational);
  });
  EXPECT_FALSE(kept(keeper)) << "the line's wait for a mandatory device is decided anew at every start";

  // The operator stops it again; the bridge stops (the store writes what is pending): kept on disk.
  on_loop([&] {
    line = {};
    node.hold(co::NmtCommand::stop);
    keeper.operator_command(co::NmtCommand::stop);
  });
  ASSERT_TRUE(kept(keeper));
  loop_->stop();
  store.reset();
  EXPECT_NE(lb::test::read_text(dir + "/line.holds").find("extrusion 5 cia420-4@3.1 operator-stop "), std::string::npos)
      << lb::test::read_text(dir + "/line.holds");
}

// A line's stop kept from before on a bus that has no mandatory device any more (no line view):
// held stopped as it was, still the line's, until an operator's command makes it theirs.
TEST_F(SetValueStoreHoldKeeper, ALinesStopWithoutALineIsKeptUntilAnOperatorActs) {
  const auto dir = temp_dir("noline");
  std::ofstream(dir + "/line.holds") << "format 1\nextrusion 5 cia420-4@3.1 line-stop 1700000000 mandatory device "
                                        "saw2 its heartbeat was lost\n";
  auto store = open_store(dir);
  co::RemoteNode node(*loop_, 5, 300ms, true);
  HoldKeeper keeper(*loop_, node, *store, kSaw, "saw1");
  ASSERT_TRUE(keeper.restore());
  EXPECT_EQ(node.operator_hold(), co::NmtCommand::stop);
  loop_->start();
  auto now = kept(keeper);
  ASSERT_TRUE(now);
  EXPECT_EQ(now->holder, KeptHold::Holder::line_stop);
  EXPECT_EQ(now->since_s, kSince);
  EXPECT_NE(on_loop([&] { return keeper.note(); }).find("kept from before the bridge restarted"), std::string::npos);
  on_loop([&] {
    node.hold(co::NmtCommand::stop);
    keeper.operator_command(co::NmtCommand::stop);
  });
  now = kept(keeper);
  ASSERT_TRUE(now);
  EXPECT_EQ(now->holder, KeptHold::Holder::operator_stop);
}
