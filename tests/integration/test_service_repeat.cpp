// A service request asked again runs once (the real bridge, simulator and bus): a client whose
// answer is lost writes the same request again, naming the first by its sample identity as
// related sample identity (README "Requests written faster than read"). The bridge must answer
// the repeat with the first answer and must not press a momentary command a second time: what is
// checked is the saw's RPDO1 on the bus (runs of frames with the manual-cut bit), not a counter.
// A repeat that asks something else than the request it names is refused, under its own identity.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <vector>

#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/eventually.hpp"
#include "support/line_harness.hpp"
#include "support/raw_command_client.hpp"
#include "support/spy_waits.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using eprosima::fastrtps::rtps::SampleIdentity;
using eprosima::fastrtps::rtps::WriteParams;
using lb::ddsl::QosKind;

namespace {

constexpr unsigned kManualCutBit = 3;  // saw control word 6040h (profile-decisions.md, saw 1.0 order)

// Separate runs of RPDO1 frames of the node with the bit set: one per press.
bool has_bit(const lb::can::CanFrame& f, unsigned bit) {
  return f.len >= 2 && ((f.data[0] | f.data[1] << 8) >> bit & 1U) != 0;
}

unsigned presses(lb::test::BusSpy& spy, std::uint8_t node, unsigned bit) {
  unsigned runs = 0;
  bool in = false;
  for (const auto& f : spy.frames(0x200u + node)) {
    const bool on = has_bit(f, bit);
    if (on && !in) ++runs;
    in = on;
  }
  return runs;
}

// A press stamped after `after_ns` and the frame that clears it, both at the spy.
bool pressed_and_released_after(lb::test::BusSpy& spy, std::uint8_t node, unsigned bit, std::int64_t after_ns) {
  bool pressed = false;
  for (const auto& f : spy.frames(0x200u + node)) {
    if (f.timestamp_ns <= after_ns) continue;
    if (has_bit(f, bit)) {
      pressed = true;
    } else if (pressed) {
      return true;
    }
  }
  return false;
}

}  // namespace

TEST(ServiceRepeat, ACommandAskedAgainIsPressedOnceAndAnsweredWithTheFirstAnswer) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  lb::test::LineHarness line("repeat", 36);
  line.start("  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 1000}\n");
  auto saw = line.collect<msg::SawStatusPubSubType>("saw1", "status", QosKind::state);
  ASSERT_TRUE(saw.wait_last(30s, [](const msg::SawStatus& s) {
    return s.health().online() && s.health().nmt_state() == msg::NMT_OPERATIONAL;
  })) << line.logs();

  // A raw client: the request writer and the reply reader of the line-wide command service.
  lb::test::RawCommandClient client(line.dds(), lb::ddsl::line_service_path(line.line(), "command"));
  ASSERT_TRUE(client.matched(20s)) << line.logs();

  srv::Command_Request cut;
  cut.device("saw1");
  cut.command("manual_cut");
  WriteParams first_params;
  ASSERT_TRUE(client.write(cut, first_params));
  const SampleIdentity first = first_params.sample_identity();
  const auto ask_again = [&] {
    WriteParams again;
    again.related_sample_identity(first);
    ASSERT_TRUE(client.write(cut, again));
    EXPECT_NE(again.sample_identity(), first) << "a repeat is a sample of its own";
  };
  ask_again();  // at once: the first is still being pressed (at least 100 ms)
  ASSERT_TRUE(client.wait_for(first, 1, 10s)) << line.logs();
  const std::size_t before = client.of(first).size();
  ask_again();  // after its answer: as a client whose answer was lost does
  ASSERT_TRUE(client.wait_for(first, before + 1, 10s)) << "the repeat is answered, to the first request\n"
                                                       << line.logs();

  const auto answers = client.of(first);
  ASSERT_GE(answers.size(), 2u);
  EXPECT_TRUE(answers.front().success()) << answers.front().message();
  EXPECT_GE(answers.front().held_ms(), 100.0);
  for (const auto& a : answers) {
    EXPECT_EQ(a.success(), answers.front().success());
    EXPECT_EQ(a.frames(), answers.front().frames()) << "the first answer, not a second press's";
    EXPECT_EQ(a.held_ms(), answers.front().held_ms()) << "the first answer, not a second press's";
    EXPECT_EQ(a.message(), answers.front().message());
  }

  // A new request (no related identity) is pressed again: the count below sees a second press.
  WriteParams next_params;
  const std::int64_t asked_ns = lb::test::bus_now_ns();
  ASSERT_TRUE(client.write(cut, next_params));
  ASSERT_TRUE(client.wait_for(next_params.sample_identity(), 1, 10s)) << line.logs();
  EXPECT_TRUE(client.of(next_params.sample_identity()).front().success());
  ASSERT_TRUE(
      lb::test::eventually(10s, [&] { return pressed_and_released_after(line.spy(), 3, kManualCutBit, asked_ns); }))
      << "the new press and its clearing frame never reached the spy\n"
      << line.logs();
  EXPECT_EQ(presses(line.spy(), 3, kManualCutBit), 2u) << "one press per request, none per repeat";

  // A "repeat" that names the first request but asks something else is not that request: it is
  // refused, answered under its own identity, and is not given the first cut's result.
  srv::Command_Request other;
  other.device("saw1");
  other.command("tip_pulse");
  const std::size_t first_answers = client.of(first).size();
  WriteParams mismatched;
  mismatched.related_sample_identity(first);
  ASSERT_TRUE(client.write(other, mismatched));
  ASSERT_TRUE(client.wait_for(mismatched.sample_identity(), 1, 10s))
      << "a repeat with other content got no answer of its own\n"
      << line.logs();
  const auto refusal = client.of(mismatched.sample_identity()).front();
  EXPECT_FALSE(refusal.success());
  EXPECT_NE(refusal.message().find("asks something else"), std::string::npos) << refusal.message();
  EXPECT_EQ(client.of(first).size(), first_answers) << "the first request's answer went to another request";
}
