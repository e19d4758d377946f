// RequestLedger: a request asked again is run once, its repeats get the first answer; a repeat
// names only its own writer's earlier requests and must ask the same; the ledger forgets answered
// requests by count and by age, never one still running, and refuses new ones when too many run.
#include <gtest/gtest.h>

#include <string>

#include "dds/request_ledger.hpp"

namespace {

using Ledger = lb::ddsl::RequestLedger<std::string>;
using eprosima::fastrtps::rtps::GUID_t;
using eprosima::fastrtps::rtps::SampleIdentity;
using eprosima::fastrtps::rtps::SequenceNumber_t;

GUID_t writer(std::uint8_t n) {
  GUID_t g;
  g.guidPrefix.value[0] = n;
  g.entityId.value[3] = 0x03;
  return g;
}

SampleIdentity sample(std::uint8_t w, std::int32_t sn) {
  SampleIdentity id;
  id.writer_guid(writer(w));
  id.sequence_number(SequenceNumber_t(0, static_cast<std::uint32_t>(sn)));
  return id;
}

eprosima::fastdds::dds::SampleInfo info(SampleIdentity self, SampleIdentity related = SampleIdentity::unknown()) {
  eprosima::fastdds::dds::SampleInfo i;
  i.sample_identity = self;
  i.related_sample_identity = related;
  return i;
}

// Two different requests' contents (RequestLedger::Fingerprint).
constexpr Ledger::Fingerprint kCut = 0xC07;
constexpr Ledger::Fingerprint kReset = 0x4E5E7;

}  // namespace

TEST(RequestLedger, ARepeatNamesAnEarlierRequestOfItsOwnWriter) {
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5))), sample(1, 5)) << "no related identity: a request of its own";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(1, 2))), sample(1, 2)) << "a repeat of sample 2";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(2, 2))), sample(1, 5))
      << "another writer's request: not a repeat";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(1, 5))), sample(1, 5)) << "itself";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(1, 9))), sample(1, 5)) << "a later sample cannot be repeated";
}

TEST(RequestLedger, ARequestRunsOnceAndItsRepeatsGetTheFirstAnswer) {
  Ledger ledger;
  EXPECT_EQ(ledger.admit(sample(1, 1), kCut).seen, Ledger::Seen::first);
  auto again = ledger.admit(sample(1, 1), kCut);
  EXPECT_EQ(again.seen, Ledger::Seen::in_progress);
  EXPECT_FALSE(again.answer);
  ledger.answered(sample(1, 1), "done");
  ledger.answered(sample(1, 1), "done twice");  // a handler that answers twice: the first counts
  again = ledger.admit(sample(1, 1), kCut);
  EXPECT_EQ(again.seen, Ledger::Seen::answered);
  ASSERT_TRUE(again.answer);
  EXPECT_EQ(*again.answer, "done");
  EXPECT_EQ(ledger.admit(sample(1, 2), kCut).seen, Ledger::Seen::first) << "the writer's next request is new";
  EXPECT_EQ(ledger.admit(sample(2, 1), kCut).seen, Ledger::Seen::first) << "another writer's first request is new";
  ledger.answered(sample(3, 1), "never asked");
  EXPECT_EQ(ledger.admit(sample(3, 1), kCut).seen, Ledger::Seen::first) << "an answer to nothing recorded is not kept";
}

// A repeat that names a request but asks something else (another command) is refused, whether
// the first still runs or was answered; the first request's own repeats are not affected.
TEST(RequestLedger, ARepeatWithOtherContentIsRefusedNotAnsweredWithTheFirstResult) {
  Ledger ledger;
  ASSERT_EQ(ledger.admit(sample(1, 1), kCut).seen, Ledger::Seen::first);
  EXPECT_EQ(ledger.admit(sample(1, 1), kReset).seen, Ledger::Seen::conflicting) << "while the first runs";
  EXPECT_EQ(ledger.in_progress(), 1u) << "the refusal recorded nothing";
  ledger.answered(sample(1, 1), "cut done");
  const auto other = ledger.admit(sample(1, 1), kReset);
  EXPECT_EQ(other.seen, Ledger::Seen::conflicting) << "once answered";
  EXPECT_FALSE(other.answer) << "the first request's result went to a request that asked something else";
  const auto same = ledger.admit(sample(1, 1), kCut);
  EXPECT_EQ(same.seen, Ledger::Seen::answered);
  EXPECT_EQ(same.answer.value_or(""), "cut done");
}

// Under a flood of new requests, one still running is never forgotten: its repeat must not run it
// again (a second manual cut). Beyond kMaxInProgress running, new requests are refused instead.
TEST(RequestLedger, ARequestStillRunningIsNeverForgottenAndAFloodBeyondTheBoundIsRefused) {
  Ledger ledger;
  const auto t0 = Ledger::Clock::now();
  ASSERT_EQ(ledger.admit(sample(1, 1), kCut, t0).seen, Ledger::Seen::first);  // the cut: runs long
  std::size_t busy = 0;
  for (std::int32_t i = 2; i <= static_cast<std::int32_t>(4 * Ledger::kMaxInProgress); ++i) {
    const auto seen = ledger.admit(sample(2, i), kReset, t0).seen;
    ASSERT_TRUE(seen == Ledger::Seen::first || seen == Ledger::Seen::busy) << "request " << i;
    if (seen == Ledger::Seen::busy) ++busy;
  }
  EXPECT_EQ(ledger.admit(sample(1, 1), kCut, t0 + Ledger::kKeep * 2).seen, Ledger::Seen::in_progress)
      << "the running cut was forgotten: its repeat would cut again";
  EXPECT_EQ(ledger.in_progress(), Ledger::kMaxInProgress);
  EXPECT_EQ(busy, 4 * Ledger::kMaxInProgress - Ledger::kMaxInProgress);
  // Room again once one is answered; the refused ones were never recorded.
  ledger.answered(sample(2, 2), "reset done", t0);
  EXPECT_EQ(ledger.admit(sample(3, 1), kReset, t0).seen, Ledger::Seen::first);
  EXPECT_EQ(ledger.admit(sample(3, 2), kReset, t0).seen, Ledger::Seen::busy);
}

TEST(RequestLedger, ForgetsTheOldestAnsweredBeyondItsCapacity) {
  Ledger ledger;
  const auto t0 = Ledger::Clock::now();
  for (std::size_t i = 1; i <= Ledger::kCapacity + 10; ++i) {
    ASSERT_EQ(ledger.admit(sample(1, static_cast<std::int32_t>(i)), kCut, t0).seen, Ledger::Seen::first);
    ledger.answered(sample(1, static_cast<std::int32_t>(i)), "answer " + std::to_string(i), t0);
  }
  EXPECT_EQ(ledger.size(), Ledger::kCapacity);
  const auto newest = static_cast<std::int32_t>(Ledger::kCapacity + 10);
  auto kept = ledger.admit(sample(1, newest), kCut, t0);
  EXPECT_EQ(kept.seen, Ledger::Seen::answered);
  EXPECT_EQ(kept.answer.value_or(""), "answer " + std::to_string(newest));
  EXPECT_EQ(ledger.admit(sample(1, 1), kCut, t0).seen, Ledger::Seen::first) << "the oldest was forgotten: run again";
  EXPECT_EQ(ledger.size(), Ledger::kCapacity + 1) << "the answered ones and the one running again";
}

TEST(RequestLedger, ForgetsWhatWasAnsweredLongerAgoThanItKeeps) {
  Ledger ledger;
  const auto t0 = Ledger::Clock::now();
  ledger.admit(sample(1, 1), kCut, t0);
  ledger.answered(sample(1, 1), "early", t0);
  EXPECT_EQ(ledger.admit(sample(1, 1), kCut, t0 + Ledger::kKeep).seen, Ledger::Seen::answered) << "kept for kKeep";
  EXPECT_EQ(ledger.admit(sample(1, 1), kCut, t0 + Ledger::kKeep + std::chrono::milliseconds(1)).seen,
            Ledger::Seen::first);
  EXPECT_EQ(ledger.size(), 1u);
}
