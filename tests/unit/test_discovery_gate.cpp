// The discovery gate (dds/discovery_gate.hpp) on RTPS messages written here by hand from OMG
// DDSI-RTPS 2.3 (9.4: header, DATA, INFO_SRC, HEARTBEAT; 9.6.2.2: the participant's parameters;
// 9.6.3: the key hash and status info of a disposal) and DDS Security 1.1 (PID_IDENTITY_TOKEN
// 0x1001): what reaches Fast DDS of participants that never proved themselves, and that proven
// ones and this participant's own messages always pass. The gate in a real participant under a
// real flood: tests/integration/test_discovery_flood.cpp.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <vector>

#include "dds/discovery_gate.hpp"

using lb::ddsl::DiscoveryGate;
using lb::ddsl::GateLimits;
using lb::ddsl::GuidPrefix;
using namespace std::chrono_literals;
using Clock = DiscoveryGate::Clock;
using Bytes = std::vector<std::uint8_t>;

namespace {

void le16(Bytes& m, std::uint16_t v) {
  m.push_back(static_cast<std::uint8_t>(v));
  m.push_back(static_cast<std::uint8_t>(v >> 8));
}
void le32(Bytes& m, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) m.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void append(Bytes& m, const GuidPrefix& p) { m.insert(m.end(), p.begin(), p.end()); }

GuidPrefix prefix(std::uint8_t first, std::uint8_t last = 0) {
  GuidPrefix p{};
  p.fill(0x11);
  p[0] = first;
  p[11] = last;
  return p;
}

// RTPS header: "RTPS", protocol 2.3, vendor 01.0f (eProsima), the sender's GUID prefix.
Bytes header(const GuidPrefix& source) {
  Bytes m{'R', 'T', 'P', 'S', 2, 3, 0x01, 0x0f};
  append(m, source);
  return m;
}

struct Announce {
  bool identity_token = true;
  bool announcer = true;  // PID_BUILTIN_ENDPOINT_SET bit 0: it has a participant announcer
  std::int32_t sn_high = 0;
  std::uint32_t sn = 1;             // writerSN's low word
  std::optional<GuidPrefix> named;  // PID_PARTICIPANT_GUID's prefix (default: the sender's)
  bool goodbye = false;             // its own unregister-dispose (status info inline, its key as payload)
};

// INFO_TS then DATA(p) (little-endian): readerId unknown, writerId 000100c2, PL_CDR_LE payload
// with PID_PARTICIPANT_GUID (0x0050), PID_BUILTIN_ENDPOINT_SET (0x0058), a lease (0x0002) and,
// secured, PID_IDENTITY_TOKEN (0x1001, one class id string).
Bytes announcement(const GuidPrefix& source, const Announce& a = {}) {
  Bytes m = header(source);
  m.insert(m.end(), {0x09, 0x01, 8, 0});  // INFO_TS, little-endian, 8 bytes
  le32(m, 1'700'000'000);
  le32(m, 0);
  Bytes body;
  le16(body, 0);                                      // extraFlags
  le16(body, 16);                                     // octetsToInlineQos
  body.insert(body.end(), {0, 0, 0, 0});              // readerId: unknown
  body.insert(body.end(), {0x00, 0x01, 0x00, 0xc2});  // writerId: SPDP writer
  le32(body, static_cast<std::uint32_t>(a.sn_high));  // writerSN high
  le32(body, a.sn);                                   // writerSN low
  if (a.goodbye) {
    // Inline QoS: PID_STATUS_INFO disposed|unregistered; then the key only (PID_PARTICIPANT_GUID).
    le16(body, 0x0071);
    le16(body, 4);
    body.insert(body.end(), {0, 0, 0, 0x03});
    le16(body, 0x0001);
    le16(body, 0);
    body.insert(body.end(), {0x00, 0x03, 0x00, 0x00});
    le16(body, 0x0050);
    le16(body, 16);
    append(body, a.named.value_or(source));
    body.insert(body.end(), {0x00, 0x00, 0x01, 0xc1});
    le16(body, 0x0001);
    le16(body, 0);
    m.insert(m.end(), {0x15, 0x0b});  // DATA, little-endian, inline QoS, key
    le16(m, static_cast<std::uint16_t>(body.size()));
    m.insert(m.end(), body.begin(), body.end());
    return m;
  }
  body.insert(body.end(), {0x00, 0x03, 0x00, 0x00});  // PL_CDR_LE
  le16(body, 0x0050);
  le16(body, 16);
  append(body, a.named.value_or(source));
  body.insert(body.end(), {0x00, 0x00, 0x01, 0xc1});
  le16(body, 0x0058);
  le16(body, 4);
  le32(body, a.announcer ? 0x00000c3f : 0x00000c3e);
  le16(body, 0x0002);  // lease 300 s
  le16(body, 8);
  le32(body, 300);
  le32(body, 0);
  if (a.identity_token) {
    le16(body, 0x1001);
    le16(body, 24);
    le32(body, 20);  // string length with its NUL
    const char kClass[20] = "DDS:Auth:PKI-DH:1.0";
    body.insert(body.end(), kClass, kClass + 20);
  }
  le16(body, 0x0001);  // sentinel
  le16(body, 0);
  m.insert(m.end(), {0x15, 0x05});  // DATA, little-endian, data present
  le16(m, static_cast<std::uint16_t>(body.size()));
  m.insert(m.end(), body.begin(), body.end());
  return m;
}

// A vendor-specific submessage (0x80..0xff, DDSI-RTPS 9.4.5.1.1) appended, as Fast DDS 2.9 built
// with statistics appends one to every message it sends, announcements included.
Bytes with_vendor_submessage(Bytes m) {
  m.insert(m.end(), {0x80, 0x01, 8, 0, 1, 2, 3, 4, 5, 6, 7, 8});
  return m;
}

// A HEARTBEAT of the sender's SEDP publications writer (000003c2) to its reader (000003c7).
Bytes heartbeat(const GuidPrefix& source) {
  Bytes m = header(source);
  m.insert(m.end(), {0x07, 0x01, 28, 0});
  m.insert(m.end(), {0x00, 0x00, 0x03, 0xc7, 0x00, 0x00, 0x03, 0xc2});
  le32(m, 0);
  le32(m, 1);
  le32(m, 0);
  le32(m, 1);
  le32(m, 1);
  return m;
}

// The writerSN of the first DATA in a message built above (header 20 + INFO_TS 12 + submessage
// header 4 + extraFlags..writerId 12): high and low word.
std::uint32_t word_at(const Bytes& m, std::size_t at) {
  return m[at] | (m[at + 1] << 8) | (m[at + 2] << 16) | (static_cast<std::uint32_t>(m[at + 3]) << 24);
}
std::uint32_t sn_high(const Bytes& m) { return word_at(m, 20 + 12 + 4 + 12); }
std::uint32_t sn_low(const Bytes& m) { return word_at(m, 20 + 12 + 4 + 12 + 4); }

// What the gate hands Fast DDS to make it forget a participant (DiscoveryGate::due): the
// participant's last announcement alone in a message (header 20, then the DATA built above
// without its INFO_TS), with a lease of 1 s.
struct LeaseEnd {
  GuidPrefix source{};
  std::uint32_t sn_high = 0, sn_low = 0;
  std::uint32_t lease_s = 0, lease_fraction = 0;
};
std::optional<LeaseEnd> lease_end(const Bytes& m) {
  // DATA at 20: its writerSN at 20 + 4 + 12; payload at 20 + 24: encapsulation 4,
  // PID_PARTICIPANT_GUID 4 + 16, PID_BUILTIN_ENDPOINT_SET 4 + 4, then the lease's header 4.
  constexpr std::size_t kLeaseAt = 20 + 24 + 4 + 20 + 8 + 4;
  if (m.size() < kLeaseAt + 8 || m[20] != 0x15 || m[20 + 1] != 0x05) return std::nullopt;
  if (m[kLeaseAt - 4] != 0x02 || m[kLeaseAt - 3] != 0x00) return std::nullopt;
  LeaseEnd e;
  std::copy(m.begin() + 8, m.begin() + 20, e.source.begin());
  e.sn_high = word_at(m, 20 + 16);
  e.sn_low = word_at(m, 20 + 20);
  e.lease_s = word_at(m, kLeaseAt);
  e.lease_fraction = word_at(m, kLeaseAt + 4);
  return e;
}
// The participants whose lease the handed messages end (1 s, fraction 0); a goodbye or anything
// else fails the test.
std::vector<GuidPrefix> forgotten(const std::vector<Bytes>& handed) {
  std::vector<GuidPrefix> out;
  for (const auto& m : handed) {
    const auto e = lease_end(m);
    EXPECT_TRUE(e.has_value()) << "not an announcement with its lease ended";
    if (!e) continue;
    EXPECT_EQ(e->lease_s, 1U);
    EXPECT_EQ(e->lease_fraction, 0U);
    out.push_back(e->source);
  }
  return out;
}

// Designated initializers without every member warn (-Wmissing-field-initializers): built so.
template <class T, class Set>
T with(Set set) {
  T t;
  set(t);
  return t;
}
Announce unsecured() {
  return with<Announce>([](Announce& a) { a.identity_token = false; });
}
Announce numbered(std::uint32_t sn, std::int32_t high = 0) {
  return with<Announce>([sn, high](Announce& a) {
    a.sn = sn;
    a.sn_high = high;
  });
}
Announce goodbye_numbered(std::uint32_t sn) {
  return with<Announce>([sn](Announce& a) {
    a.sn = sn;
    a.goodbye = true;
  });
}

struct Fixture {
  explicit Fixture(DiscoveryGate::Proof proof = DiscoveryGate::Proof::authentication, GateLimits limits = {})
      : gate(proof, limits) {
    gate.set_local(prefix(0x90));
  }
  DiscoveryGate::Verdict offer(const Bytes& m, Clock::time_point at) { return gate.inspect(m, rewritten, at); }
  // The second announcement (the first lets nothing through): what Fast DDS got.
  Bytes admit(const GuidPrefix& p, Clock::time_point at, const Announce& a = {}) {
    EXPECT_FALSE(offer(announcement(p, a), at).pass);
    const auto v = offer(announcement(p, a), at + 50ms);
    EXPECT_TRUE(v.pass);
    EXPECT_TRUE(v.rewritten);
    return rewritten;
  }
  DiscoveryGate gate;
  Bytes rewritten;
  Clock::time_point t0 = Clock::now();
};

TEST(DiscoveryGate, AParticipantsFirstAnnouncementIsDroppedItsSecondPassesPending) {
  Fixture f;
  const auto p = prefix(0xa0);
  EXPECT_FALSE(f.offer(announcement(p), f.t0).pass);
  EXPECT_EQ(f.gate.counts().pending_now, 0);
  const auto v = f.offer(announcement(p), f.t0 + 250ms);
  EXPECT_TRUE(v.pass);
  EXPECT_TRUE(v.announcement);
  EXPECT_EQ(f.gate.counts().pending_now, 1);
  EXPECT_EQ(f.gate.counts().admitted, 1U);
  // Its messages pass while pending (a handshake needs them).
  EXPECT_TRUE(f.offer(heartbeat(p), f.t0 + 300ms).pass);
}

TEST(DiscoveryGate, MessagesOfAParticipantNeverLetInAreDroppedAndOwnMessagesPass) {
  Fixture f;
  EXPECT_FALSE(f.offer(heartbeat(prefix(0xa1)), f.t0).pass);
  EXPECT_TRUE(f.offer(heartbeat(prefix(0x90)), f.t0).pass);
  EXPECT_TRUE(f.offer(announcement(prefix(0x90)), f.t0).pass);
  EXPECT_FALSE(f.offer(announcement(prefix(0x90)), f.t0).rewritten);
}

TEST(DiscoveryGate, ASecuredGateIgnoresAnnouncementsWithoutAnIdentityToken) {
  Fixture f;
  const auto p = prefix(0xa2);
  for (int i = 0; i < 5; ++i) EXPECT_FALSE(f.offer(announcement(p, unsecured()), f.t0 + i * 100ms).pass);
  EXPECT_EQ(f.gate.counts().unsecured_ignored, 5U);
  EXPECT_EQ(f.gate.counts().pending_now, 0);
  // An unsecured gate (a line without security) takes them.
  Fixture plain(DiscoveryGate::Proof::traffic);
  plain.admit(p, plain.t0, unsecured());
}

TEST(DiscoveryGate, AnAnnouncementOfAnotherParticipantThanItsSenderIsDropped) {
  Fixture f;
  const auto p = prefix(0xa3);
  for (int i = 0; i < 3; ++i)
    EXPECT_FALSE(
        f.offer(announcement(p, with<Announce>([](Announce& a) { a.named = prefix(0xa4); })), f.t0 + i * 50ms).pass);
  EXPECT_EQ(f.gate.counts().pending_now, 0);
}

TEST(DiscoveryGate, PendingParticipantsAreBoundedTheNextOneWaits) {
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) { l.pending = 2; }));
  f.admit(prefix(0xb1), f.t0);
  f.admit(prefix(0xb2), f.t0);
  EXPECT_FALSE(f.offer(announcement(prefix(0xb3)), f.t0).pass);
  EXPECT_FALSE(f.offer(announcement(prefix(0xb3)), f.t0 + 50ms).pass);
  EXPECT_EQ(f.gate.counts().pending_now, 2);
  EXPECT_EQ(f.gate.counts().waited, 1U);
  // One proves itself: the one waiting gets in at its next announcement.
  f.gate.authenticated(prefix(0xb1), f.t0 + 1s);
  EXPECT_TRUE(f.offer(announcement(prefix(0xb3)), f.t0 + 1250ms).pass);
  EXPECT_EQ(f.gate.counts().pending_now, 2);
  EXPECT_EQ(f.gate.counts().proven_now, 1);
}

TEST(DiscoveryGate, ANewcomerTakesThePlaceOfTheLongestPendingNeitherSideSentAnythingTo) {
  // Below the local prefix (0x90...): they start the handshake; until they do, this side sent them
  // nothing and holds a proxy only.
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) {
              l.waiting = 2;
              l.replaceable_after = 4s;
              l.prove_within = 20s;
            }));
  const auto p = [](int i) { return prefix(0x80, static_cast<std::uint8_t>(i)); };
  f.admit(p(0), f.t0);
  // p0 sent its request: a handshake under way (it now holds this side's reply, in the other quota).
  EXPECT_TRUE(f.offer(heartbeat(p(0)), f.t0 + 200ms).pass);
  f.admit(p(1), f.t0 + 500ms);
  f.admit(p(2), f.t0 + 1s);
  EXPECT_FALSE(f.offer(announcement(p(3)), f.t0 + 3s).pass);
  EXPECT_FALSE(f.offer(announcement(p(3)), f.t0 + 4s).pass) << "p1 had 3.5 s only";
  // p1 had its 4 s, silent: its lease is ended, and p3 gets its place once Fast DDS dropped it.
  EXPECT_FALSE(f.offer(announcement(p(3)), f.t0 + 4600ms).pass) << "p1 is still in Fast DDS";
  const auto due = forgotten(f.gate.due(f.t0 + 4600ms));
  ASSERT_EQ(due.size(), 1U);
  EXPECT_EQ(due[0], p(1)) << "the oldest, p0, is in its handshake: never replaced";
  EXPECT_EQ(f.gate.counts().pending_now, 2);
  f.gate.departed(p(1), f.t0 + 4700ms);
  EXPECT_TRUE(f.offer(announcement(p(3)), f.t0 + 4800ms).pass);
  EXPECT_EQ(f.gate.counts().pending_now, 3);
  EXPECT_FALSE(f.offer(heartbeat(p(1)), f.t0 + 5s).pass);
  EXPECT_TRUE(f.offer(heartbeat(p(0)), f.t0 + 5s).pass);
  EXPECT_TRUE(f.offer(heartbeat(p(2)), f.t0 + 5s).pass);
}

TEST(DiscoveryGate, ParticipantsThisSideStartedAHandshakeWithAreNeitherReplacedNorEvictedEarly) {
  // Above the local prefix: this side sends each its request at once. Cutting that short could
  // leave a real one answering a later request with its reply to the first (Fast DDS 2.9.1).
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) {
              l.pending = 2;
              l.replaceable_after = 3s;
              l.prove_within = 10s;
              l.talk_within = 60s;
            }));
  f.admit(prefix(0xb1), f.t0);
  f.admit(prefix(0xb2), f.t0);
  EXPECT_FALSE(f.offer(announcement(prefix(0xb3)), f.t0 + 20s).pass);
  EXPECT_FALSE(f.offer(announcement(prefix(0xb3)), f.t0 + 20100ms).pass) << "no replacing: it waits";
  EXPECT_TRUE(f.gate.due(f.t0 + 30s).empty()) << "silent, yet its handshake is under way";
  EXPECT_EQ(forgotten(f.gate.due(f.t0 + 61s)).size(), 2U);
  EXPECT_FALSE(f.offer(announcement(prefix(0xb3)), f.t0 + 61s + 500ms).pass) << "both are still in Fast DDS";
  // Fast DDS never reports one dropped (it had no proxy for it): it goes all the same.
  f.gate.departed(prefix(0xb1), f.t0 + 62s);
  EXPECT_TRUE(f.offer(announcement(prefix(0xb3)), f.t0 + 62s).pass);
  EXPECT_FALSE(f.offer(announcement(prefix(0xb4)), f.t0 + 63s).pass);
  EXPECT_FALSE(f.offer(announcement(prefix(0xb4)), f.t0 + 63s + 50ms).pass) << "b2 is still counted";
  EXPECT_TRUE(f.gate.due(f.t0 + 66s + 100ms).empty());
  EXPECT_TRUE(f.offer(announcement(prefix(0xb4)), f.t0 + 66s + 200ms).pass) << "b2 had its 5 s to go";
}

TEST(DiscoveryGate, AParticipantsAnnouncementsReachFastDdsInAnEpochOfTheGatesWhateverNumberTheyCarry) {
  Fixture f;
  // A forger's highest number: the gate's epoch replaces the high word, the low word stays.
  const auto got = f.admit(prefix(0xb4), f.t0, numbered(0xfffffff0, 0x7fffffff));
  const auto epoch = sn_high(got);
  EXPECT_NE(epoch, 0x7fffffffU);
  EXPECT_GE(epoch, 1U);
  EXPECT_EQ(sn_low(got), 0xfffffff0U);
  // Every announcement of it: the same epoch.
  ASSERT_TRUE(f.offer(announcement(prefix(0xb4), numbered(0xfffffff1)), f.t0 + 1s).rewritten);
  EXPECT_EQ(sn_high(f.rewritten), epoch);
  EXPECT_EQ(sn_low(f.rewritten), 0xfffffff1U);
  // The next participant let in: a later epoch.
  EXPECT_GT(sn_high(f.admit(prefix(0xb9), f.t0 + 2s)), epoch);
}

TEST(DiscoveryGate, AProvenParticipantsUpdatesReachFastDdsInItsOrder) {
  Fixture f;
  const auto p = prefix(0xbb);
  const auto epoch = sn_high(f.admit(p, f.t0));
  f.gate.authenticated(p, f.t0 + 1s);
  // Its periodic announcement, then an update of its data: the same epoch, its own numbers in
  // order, so Fast DDS takes each (its goodbye: AParticipantsOwnGoodbyeBecomesTheEndOfItsLease).
  for (const auto& [a, low] : {std::pair{numbered(1), 1U}, {numbered(2), 2U}}) {
    const auto v = f.offer(announcement(p, a), f.t0 + 2s);
    ASSERT_TRUE(v.pass);
    ASSERT_TRUE(v.rewritten);
    EXPECT_EQ(sn_high(f.rewritten), epoch);
    EXPECT_EQ(sn_low(f.rewritten), low);
  }
  // Fast DDS says it is gone: the same participant (same prefix) starting again is a newcomer in
  // a later epoch, so Fast DDS takes its numbers from 1 again.
  f.gate.departed(p);
  EXPECT_GT(sn_high(f.admit(p, f.t0 + 3s)), epoch);
}

// Never a goodbye (Fast DDS 2.9.1 can deadlock removing a participant on a receive thread,
// discovery_gate.hpp): its own last announcement again, numbered above it, with a lease of 1 s, so
// that Fast DDS's event thread drops it.
TEST(DiscoveryGate, ASilentPendingParticipantsLeaseIsEndedAfterTheDeadlineAndItMayComeBackAsANewcomer) {
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) { l.prove_within = 10s; }));
  const auto p = prefix(0x85);  // below the local prefix: this side waits for its request, sends nothing
  const auto epoch = sn_high(f.admit(p, f.t0, numbered(0xffffffff)));
  EXPECT_TRUE(f.gate.due(f.t0 + 9s).empty());
  const auto due = f.gate.due(f.t0 + 10100ms);
  ASSERT_EQ(forgotten(due), std::vector<GuidPrefix>{p});
  const auto end = *lease_end(due[0]);
  EXPECT_GT(end.sn_high, epoch) << "Fast DDS takes an update only above the last announcement's number";
  EXPECT_EQ(end.sn_low, 0xffffffffU) << "its own announcement, as it was (the high word aside)";
  EXPECT_EQ(f.gate.counts().pending_now, 0);
  EXPECT_EQ(f.gate.counts().evicted, 1U);
  // Nothing of it passes until Fast DDS dropped it (nothing may renew its lease there); then its
  // other messages are dropped and its next announcement lets it in again, numbered above.
  EXPECT_FALSE(f.offer(announcement(p), f.t0 + 10500ms).pass);
  f.gate.departed(p, f.t0 + 11s);
  EXPECT_FALSE(f.offer(heartbeat(p), f.t0 + 11s).pass);
  EXPECT_TRUE(f.offer(announcement(p), f.t0 + 12s).pass);
  EXPECT_GT(sn_high(f.rewritten), end.sn_high);
  EXPECT_EQ(f.gate.counts().pending_now, 1);
}

TEST(DiscoveryGate, AParticipantsOwnGoodbyeBecomesTheEndOfItsLease) {
  Fixture f;
  const auto p = prefix(0xbd);
  f.admit(p, f.t0, numbered(4));
  f.gate.authenticated(p, f.t0 + 1s);
  ASSERT_TRUE(f.offer(announcement(p, numbered(5)), f.t0 + 2s).pass);
  // Its goodbye is not handed on: the announcement it was let in with (number 4, kept once) is,
  // with a lease of 1 s, numbered above every one of its before (the later number 5 included).
  EXPECT_FALSE(f.offer(announcement(p, goodbye_numbered(6)), f.t0 + 3s).pass);
  const auto due = f.gate.due(f.t0 + 3s);
  ASSERT_EQ(forgotten(due), std::vector<GuidPrefix>{p});
  EXPECT_EQ(lease_end(due[0])->sn_low, 4U);
  EXPECT_GT(lease_end(due[0])->sn_high, sn_high(f.rewritten));
  // Pending, the same.
  const auto q = prefix(0xbe);
  f.admit(q, f.t0 + 4s);
  EXPECT_FALSE(f.offer(announcement(q, goodbye_numbered(2)), f.t0 + 5s).pass);
  EXPECT_EQ(forgotten(f.gate.due(f.t0 + 5s)), std::vector<GuidPrefix>{q});
}

TEST(DiscoveryGate, ASecuredGateLetsInNoAnnouncementWithoutALease) {
  Fixture f;
  auto m = announcement(prefix(0xbf));
  // PID_PARTICIPANT_LEASE_DURATION (0x0002) made PID_PAD (0x0000): the same length, no lease.
  constexpr std::size_t kLeasePid = 20 + 12 + 4 + 20 + 4 + 20 + 8;
  ASSERT_EQ(m[kLeasePid], 0x02);
  m[kLeasePid] = 0x00;
  EXPECT_FALSE(f.offer(m, f.t0).pass);
  EXPECT_FALSE(f.offer(m, f.t0 + 50ms).pass);
  EXPECT_EQ(f.gate.counts().pending_now, 0);
  // Unsecured, it is let in, and said goodbye to (no lease to end) when it proves nothing.
  Fixture plain(DiscoveryGate::Proof::traffic, with<GateLimits>([](GateLimits& l) { l.prove_within = 10s; }));
  auto u = announcement(prefix(0xbf), unsecured());
  u[kLeasePid] = 0x00;
  EXPECT_FALSE(plain.offer(u, plain.t0).pass);
  EXPECT_TRUE(plain.offer(u, plain.t0 + 50ms).pass);
  const auto due = plain.gate.due(plain.t0 + 11s);
  ASSERT_EQ(due.size(), 1U);
  EXPECT_EQ(due[0], DiscoveryGate::goodbye(prefix(0xbf), sn_high(plain.rewritten) + 1));
}

TEST(DiscoveryGate, AParticipantInItsHandshakeHasLongerAndIsRefusedForAWhileWhenItNeverAuthenticates) {
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) {
              l.prove_within = 10s;
              l.talk_within = 60s;
              l.refuse_for = 30s;
            }));
  const auto p = prefix(0xb5);
  f.admit(p, f.t0);
  EXPECT_TRUE(f.offer(heartbeat(p), f.t0 + 1s).pass);  // a handshake message, say
  EXPECT_TRUE(f.gate.due(f.t0 + 30s).empty()) << "a slow handshake is no reason to evict";
  EXPECT_EQ(forgotten(f.gate.due(f.t0 + 61s)), std::vector<GuidPrefix>{p});
  EXPECT_FALSE(f.offer(announcement(p), f.t0 + 61500ms).pass);
  f.gate.departed(p, f.t0 + 62s);
  // Refused for refuse_for: announcements too; then it may come in again (seen twice).
  EXPECT_FALSE(f.offer(announcement(p), f.t0 + 62s).pass);
  EXPECT_FALSE(f.offer(announcement(p), f.t0 + 90s).pass);
  EXPECT_FALSE(f.offer(announcement(p), f.t0 + 92s).pass);
  EXPECT_TRUE(f.offer(announcement(p), f.t0 + 92250ms).pass);
}

TEST(DiscoveryGate, TheGoodbyeIsADisposeUnregisterOfTheParticipantFromItsAnnouncementWriter) {
  const auto p = prefix(0xb6, 0x42);
  const auto m = DiscoveryGate::goodbye(p, 0x05040302U);
  ASSERT_GE(m.size(), 20U + 4 + 20 + 20 + 8 + 4);
  EXPECT_EQ(Bytes(m.begin(), m.begin() + 4), (Bytes{'R', 'T', 'P', 'S'}));
  EXPECT_TRUE(std::equal(p.begin(), p.end(), m.begin() + 8));
  std::size_t at = 20;
  EXPECT_EQ(m[at], 0x15);      // DATA
  EXPECT_EQ(m[at + 1], 0x03);  // little-endian, inline QoS, no data, no key
  EXPECT_EQ(m[at + 2] | (m[at + 3] << 8), 52);
  EXPECT_EQ(Bytes(m.begin() + at + 8, m.begin() + at + 12), (Bytes{0x00, 0x01, 0x00, 0xc7}));   // SPDP reader
  EXPECT_EQ(Bytes(m.begin() + at + 12, m.begin() + at + 16), (Bytes{0x00, 0x01, 0x00, 0xc2}));  // SPDP writer
  // writerSN: the epoch as high word, low word 0 (above every number of the epochs before).
  EXPECT_EQ(Bytes(m.begin() + at + 16, m.begin() + at + 24), (Bytes{0x02, 0x03, 0x04, 0x05, 0, 0, 0, 0}));
  at += 24;
  EXPECT_EQ(Bytes(m.begin() + at, m.begin() + at + 4), (Bytes{0x70, 0x00, 16, 0}));  // PID_KEY_HASH
  EXPECT_TRUE(std::equal(p.begin(), p.end(), m.begin() + at + 4));
  EXPECT_EQ(Bytes(m.begin() + at + 16, m.begin() + at + 20), (Bytes{0x00, 0x00, 0x01, 0xc1}));
  at += 20;
  EXPECT_EQ(Bytes(m.begin() + at, m.begin() + at + 8),
            (Bytes{0x71, 0x00, 4, 0, 0, 0, 0, 0x03}));  // disposed|unregistered
  at += 8;
  EXPECT_EQ(Bytes(m.begin() + at, m.begin() + at + 4), (Bytes{0x01, 0x00, 0, 0}));  // sentinel
  EXPECT_EQ(m.size(), at + 4);
}

TEST(DiscoveryGate, AnAuthenticatedParticipantIsNeverEvictedAndItsMessagesPass) {
  Fixture f;
  const auto p = prefix(0xb7);
  f.admit(p, f.t0);
  f.gate.authenticated(p, f.t0 + 1s);
  EXPECT_TRUE(f.gate.due(f.t0 + 1h).empty());
  EXPECT_TRUE(f.offer(announcement(p, numbered(7)), f.t0 + 1h).pass);
  const auto v = f.offer(heartbeat(p), f.t0 + 1h);
  EXPECT_TRUE(v.pass);
  EXPECT_FALSE(v.rewritten) << "only announcements are renumbered";
  // Gone (Fast DDS forgot it): a new participant again.
  f.gate.departed(p);
  EXPECT_EQ(f.gate.counts().proven_now, 0);
  EXPECT_FALSE(f.offer(heartbeat(p), f.t0 + 2h).pass);
}

TEST(DiscoveryGate, AFailedAuthenticationEvictsAtOnceAndRefusesForAWhile) {
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) { l.refuse_for = 30s; }));
  const auto p = prefix(0xb8);
  f.admit(p, f.t0);
  f.gate.refused(p, f.t0 + 1s);
  EXPECT_EQ(forgotten(f.gate.due(f.t0 + 1s)), std::vector<GuidPrefix>{p});
  for (int i = 2; i < 30; ++i) EXPECT_FALSE(f.offer(announcement(p), f.t0 + std::chrono::seconds(i)).pass);
}

TEST(DiscoveryGate, OnAnUnsecuredLineAParticipantProvesItselfByTakingPartInDiscovery) {
  Fixture f(DiscoveryGate::Proof::traffic);
  const auto p = prefix(0xb9);
  f.admit(p, f.t0, unsecured());
  EXPECT_TRUE(f.offer(heartbeat(p), f.t0 + 100ms).pass);
  EXPECT_EQ(f.gate.counts().proven_now, 1);
  EXPECT_TRUE(f.gate.due(f.t0 + 1h).empty());
  // A replayed announcement takes no part: evicted.
  const auto q = prefix(0xba);
  f.admit(q, f.t0, unsecured());
  EXPECT_EQ(forgotten(f.gate.due(f.t0 + 30s)), std::vector<GuidPrefix>{q});
}

TEST(DiscoveryGate, AVendorSpecificSubmessageBesideAnAnnouncementIsNoProofNorTakingPart) {
  // Unsecured: taking part proves; an announcement with Fast DDS's statistics submessage does not.
  Fixture plain(DiscoveryGate::Proof::traffic, with<GateLimits>([](GateLimits& l) { l.prove_within = 10s; }));
  const auto p = prefix(0xbc);
  EXPECT_FALSE(plain.offer(with_vendor_submessage(announcement(p, unsecured())), plain.t0).pass);
  EXPECT_TRUE(plain.offer(with_vendor_submessage(announcement(p, unsecured())), plain.t0 + 50ms).pass);
  EXPECT_EQ(plain.gate.counts().proven_now, 0);
  ASSERT_EQ(forgotten(plain.gate.due(plain.t0 + 11s)).size(), 1U);
  // Secured: it does not earn the longer deadline of a participant in its handshake.
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) {
              l.prove_within = 10s;
              l.talk_within = 60s;
            }));
  const auto q = prefix(0x85);  // below the local prefix: no handshake of this side under way
  EXPECT_FALSE(f.offer(with_vendor_submessage(announcement(q)), f.t0).pass);
  EXPECT_TRUE(f.offer(with_vendor_submessage(announcement(q)), f.t0 + 50ms).pass);
  EXPECT_TRUE(f.offer(with_vendor_submessage(announcement(q)), f.t0 + 5s).pass);
  ASSERT_EQ(forgotten(f.gate.due(f.t0 + 11s)).size(), 1U);
}

TEST(DiscoveryGate, HandshakesThisSideKeepsAreBoundedBelowFastDdsHistory) {
  // Local 0x90...: remote prefixes above it are the ones whose handshake this side starts and
  // whose final message Fast DDS keeps for as long as they stay.
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) {
              l.pending = 8;
              l.handshake_slots = 3;
            }));
  f.admit(prefix(0xc1), f.t0);
  f.gate.authenticated(prefix(0xc1), f.t0);
  f.admit(prefix(0xc2), f.t0);
  f.gate.authenticated(prefix(0xc2), f.t0);
  f.admit(prefix(0xc3), f.t0);  // pending: the third slot
  EXPECT_EQ(f.gate.counts().handshake_slots_now, 3);
  EXPECT_FALSE(f.offer(announcement(prefix(0xc4)), f.t0).pass);
  EXPECT_FALSE(f.offer(announcement(prefix(0xc4)), f.t0 + 50ms).pass);
  EXPECT_EQ(f.gate.counts().waited, 1U);
  // A participant below this one starts the handshake (and keeps its final message) itself: until
  // it sends its request this side holds nothing for it, so it is let in whatever the slots.
  f.gate.authenticated(prefix(0xc3), f.t0 + 1s);
  EXPECT_EQ(f.gate.counts().handshake_slots_now, 3);
  EXPECT_FALSE(f.offer(announcement(prefix(0x85)), f.t0 + 2s).pass);
  EXPECT_TRUE(f.offer(announcement(prefix(0x85)), f.t0 + 2050ms).pass);
  EXPECT_EQ(f.gate.counts().handshake_slots_now, 3);
  // Once authenticated it takes no slot: this side did not start its handshake.
  f.gate.authenticated(prefix(0x85), f.t0 + 3s);
  EXPECT_EQ(f.gate.counts().handshake_slots_now, 3);
  // One that holds a slot leaves: the one waiting above gets in.
  f.gate.departed(prefix(0xc1));
  EXPECT_EQ(f.gate.counts().handshake_slots_now, 2);
  EXPECT_TRUE(f.offer(announcement(prefix(0xc4)), f.t0 + 4s).pass);
  EXPECT_EQ(f.gate.counts().handshake_slots_now, 3);
}

TEST(DiscoveryGate, ParticipantsThisSideOnlyWaitsForHaveTheirOwnLargerQuota) {
  // Below the local prefix: they start the handshake; pending, this side holds a proxy only.
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) {
              l.pending = 1;
              l.waiting = 3;
            }));
  for (std::uint8_t i = 1; i <= 3; ++i) f.admit(prefix(0x80, i), f.t0);
  EXPECT_FALSE(f.offer(announcement(prefix(0x80, 4)), f.t0).pass);
  EXPECT_FALSE(f.offer(announcement(prefix(0x80, 4)), f.t0 + 50ms).pass);
  EXPECT_EQ(f.gate.counts().waited, 1U);
  // The quota of those holding a message is apart: one above the local prefix still gets in.
  f.admit(prefix(0xc0), f.t0);
  EXPECT_EQ(f.gate.counts().pending_now, 4);
  // One that sends its request holds this side's reply: it moves to that quota (and is in its
  // handshake: not replaced, a longer deadline).
  EXPECT_TRUE(f.offer(heartbeat(prefix(0x80, 1)), f.t0 + 100ms).pass);
  EXPECT_EQ(f.gate.counts().handshake_slots_now, 2);
  EXPECT_TRUE(f.offer(announcement(prefix(0x80, 4)), f.t0 + 200ms).pass);
}

TEST(DiscoveryGate, AFloodOfOneShotAnnouncementsNeverReachesFastDdsAndIsRememberedBounded) {
  Fixture f(DiscoveryGate::Proof::authentication, with<GateLimits>([](GateLimits& l) { l.remember = 100; }));
  for (std::uint32_t i = 0; i < 1000; ++i) {
    auto p = prefix(0xd0);
    p[8] = static_cast<std::uint8_t>(i >> 8);
    p[9] = static_cast<std::uint8_t>(i);
    EXPECT_FALSE(f.offer(announcement(p), f.t0 + std::chrono::milliseconds(i)).pass);
  }
  EXPECT_EQ(f.gate.counts().pending_now, 0);
  EXPECT_EQ(f.gate.counts().admitted, 0U);
  EXPECT_EQ(f.gate.counts().dropped, 1000U);
  // A real newcomer's start burst still gets in.
  f.admit(prefix(0xe0), f.t0 + 2s);
}

TEST(DiscoveryGate, AnAnnouncementWithoutItsAnnouncerEndpointOrCutShortIsDropped) {
  Fixture f;
  const auto p = prefix(0xd1);
  for (int i = 0; i < 3; ++i)
    EXPECT_FALSE(
        f.offer(announcement(p, with<Announce>([](Announce& a) { a.announcer = false; })), f.t0 + i * 50ms).pass);
  auto m = announcement(prefix(0xd2));
  m.resize(m.size() - 10);
  EXPECT_FALSE(f.offer(m, f.t0).pass);
  EXPECT_FALSE(f.offer(Bytes{'R', 'T', 'P', 'S'}, f.t0).pass);
  EXPECT_EQ(f.gate.counts().pending_now, 0);
}

TEST(DiscoveryGate, AnInfoSourceNamesTheSenderOfWhatFollows) {
  Fixture f;
  const auto proven = prefix(0xd3);
  f.admit(proven, f.t0);
  f.gate.authenticated(proven, f.t0);
  // A proven participant's message carrying an INFO_SRC of a stranger and the stranger's heartbeat.
  Bytes m = header(proven);
  m.insert(m.end(), {0x0c, 0x01, 20, 0, 0, 0, 0, 0, 2, 3, 0x01, 0x0f});
  append(m, prefix(0xd4));
  const auto hb = heartbeat(prefix(0xd4));
  m.insert(m.end(), hb.begin() + 20, hb.end());
  EXPECT_FALSE(f.offer(m, f.t0 + 1s).pass);
}

}  // namespace
