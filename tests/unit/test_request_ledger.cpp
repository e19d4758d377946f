// RequestLedger: a request asked again is run once, its repeats get the first answer; a repeat
// names only its own writer's earlier requests; the ledger forgets by count and by age.
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

}  // namespace

TEST(RequestLedger, ARepeatNamesAnEarlierRequestOfItsOwnWriter) {
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5))), sample(1, 5)) << "no related identity: a request of its own";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(1, 2))), sample(1, 2)) << "a repeat of sample 2";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(2, 2))), sample(1, 5)) << "another writer's request: not a repeat";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(1, 5))), sample(1, 5)) << "itself";
  EXPECT_EQ(Ledger::asked_as(info(sample(1, 5), sample(1, 9))), sample(1, 5)) << "a later sample cannot be repeated";
}

TEST(RequestLedger, ARequestRunsOnceAndItsRepeatsGetTheFirstAnswer) {
  Ledger ledger;
  EXPECT_EQ(ledger.admit(sample(1, 1)).seen, Ledger::Seen::first);
  auto again = ledger.admit(sample(1, 1));
  EXPECT_EQ(again.seen, Ledger::Seen::in_progress);
  EXPECT_FALSE(again.answer);
  ledger.answered(sample(1, 1), "done");
  ledger.answered(sample(1, 1), "done twice");  // a handler that answers twice: the first counts
  again = ledger.admit(sample(1, 1));
  EXPECT_EQ(again.seen, Ledger::Seen::answered);
  ASSERT_TRUE(again.answer);
  EXPECT_EQ(*again.answer, "done");
  EXPECT_EQ(ledger.admit(sample(1, 2)).seen, Ledger::Seen::first) << "the writer's next request is new";
  EXPECT_EQ(ledger.admit(sample(2, 1)).seen, Ledger::Seen::first) << "another writer's first request is new";
  ledger.answered(sample(3, 1), "never asked");
  EXPECT_EQ(ledger.admit(sample(3, 1)).seen, Ledger::Seen::first) << "an answer to nothing recorded is not kept";
}

TEST(RequestLedger, ForgetsTheOldestBeyondItsCapacity) {
  Ledger ledger;
  const auto t0 = Ledger::Clock::now();
  for (std::size_t i = 1; i <= Ledger::kCapacity + 10; ++i) {
    ASSERT_EQ(ledger.admit(sample(1, static_cast<std::int32_t>(i)), t0).seen, Ledger::Seen::first);
    ledger.answered(sample(1, static_cast<std::int32_t>(i)), "answer " + std::to_string(i));
  }
  EXPECT_EQ(ledger.size(), Ledger::kCapacity);
  const auto newest = static_cast<std::int32_t>(Ledger::kCapacity + 10);
  auto kept = ledger.admit(sample(1, newest), t0);
  EXPECT_EQ(kept.seen, Ledger::Seen::answered);
  EXPECT_EQ(kept.answer.value_or(""), "answer " + std::to_string(newest));
  EXPECT_EQ(ledger.admit(sample(1, 1), t0).seen, Ledger::Seen::first) << "the oldest was forgotten: run again";
  EXPECT_EQ(ledger.size(), Ledger::kCapacity);
}

TEST(RequestLedger, ForgetsWhatIsOlderThanItKeeps) {
  Ledger ledger;
  const auto t0 = Ledger::Clock::now();
  ledger.admit(sample(1, 1), t0);
  ledger.answered(sample(1, 1), "early");
  EXPECT_EQ(ledger.admit(sample(1, 1), t0 + Ledger::kKeep).seen, Ledger::Seen::answered) << "kept for kKeep";
  EXPECT_EQ(ledger.admit(sample(1, 1), t0 + Ledger::kKeep + std::chrono::milliseconds(1)).seen, Ledger::Seen::first);
  EXPECT_EQ(ledger.size(), 1u);
}
