#pragma once
// What a participant lets Fast DDS keep of remote participants that have not proven themselves
// (issue 41 point 1): a filter in front of its sockets (gate_transport.hpp) that reads every
// received RTPS message before Fast DDS does.
//
// Why: Fast DDS 2.9.1 keeps everything an announcement (SPDP DATA(p)) asks for, for as long as the
// announcement's own lease says (the sender's choice, up to infinite): a participant proxy, and on
// a secured participant a pending PKI-DH handshake whose message waits in a history of 100 (full:
// the next real handshake aborts the process, SecurityManager.cpp, issue 25), resent every second.
// Its own limit on remote participants keeps the first ones and drops the rest, so forged
// announcements lock real participants out for the length of their lease; and it cannot forget a
// participant (ignore_participant is unsupported in 2.9.1).
//
// So the gate decides which announcements reach Fast DDS:
// - a participant is *proven* once it authenticated (a secured participant: Fast DDS reports it
//   authorized) or, on an unsecured one, once it sent anything besides its announcement (endpoint
//   discovery, acknowledgements: what a real participant does once it knows us, and what a
//   replayed announcement never does). Proven participants and this one's own messages always
//   pass: nothing an authenticated or honest participant does is limited here;
// - an announcement of a participant never seen is dropped, and remembered: its second one is the
//   first to pass (a real participant announces several times at start and then periodically; a
//   flood of one-shot forged announcements never reaches Fast DDS at all);
// - a participant let through and not proven is *pending*. On a secured line a pending one either
//   holds a handshake message of this side (its request, when this side starts the handshake, or
//   its reply: at most `pending` of them at once, and Fast DDS's history keeps them) or this side
//   only waits for its request (a proxy, nothing sent: at most `waiting`); unsecured, at most
//   `pending` in all. A pending one is evicted when its authentication failed, when this side
//   sent it nothing and it sent nothing but announcements for `prove_within`, or else (a
//   handshake under way: cutting one short can leave a real peer stuck, engaged()) after
//   `talk_within`: Fast DDS is told its lease ended (below), so Fast DDS frees everything it held
//   for it, and until it did the evicted one keeps its place in the quotas and nothing of it
//   passes (which would renew that lease). One that took part is then refused for `refuse_for` (no new handshake with a
//   participant of another PKI every few seconds); a silent one may come in again (a forger takes new prefixes anyway).
//   A newcomer finding its quota full takes the place of the longest pending one that neither side sent anything to for
//   `replaceable_after` (a real one starts its handshake within a second or so), else it waits (its announcements
//   dropped until then);
// - a secured participant additionally never lets the pending ones and the authenticated ones
//   whose handshake it started (it keeps their final message) fill Fast DDS's handshake history:
//   at most `handshake_slots` of them;
// - on a secured participant an announcement without an identity token is dropped outright: its
//   governance never lets an unauthenticated participant in, so Fast DDS would only keep it.
// How Fast DDS is made to forget a participant: never by a goodbye (an unregister-dispose
// announcement), because Fast DDS 2.9.1 can deadlock removing a participant on a receive thread
// (caught twice by this project's flood test, 1 CI run in 10): SecurityManager::remove_participant
// destroys the participant's handshake timer while it holds its mutex and waits for the event
// thread, which may be waiting for that mutex (to encode an acknowledgement, or to remove a
// participant whose lease ended). A participant whose lease ends is removed by the event thread
// itself, which waits for nobody. So the gate keeps the announcement it let each participant in
// with and, to evict one, hands Fast DDS that announcement again with a lease of 1 s (Fast DDS
// reschedules its lease check when a lease shrinks): the event thread drops it a second later.
// A participant's own goodbye is turned into the same (it is dropped; its lease ends instead).
// Only a participant let in with an announcement that carried no lease (not Fast DDS) is said
// goodbye to (unsecured lines only: a secured gate lets no such announcement in).
// To make that work whatever sequence number a forged announcement carries (Fast DDS takes an
// update only with a sequence number above the last one's), every announcement of a participant
// let in reaches Fast DDS with the high word of its sequence number replaced by an epoch of the
// gate's, drawn when it was let in (the low word, which orders its own announcements and updates,
// stays), and the gate's last word carries a later epoch.
//
// What an attacker without a certificate can then make the process hold: `pending` participants
// with a handshake each and `waiting` without, for `prove_within` each (`talk_within` if it keeps
// sending something in their name), the remembered first sightings (`remember`, about 100 bytes
// each) and the refused ones (`refuse_for`, bounded by `remember` too).
//
// Pure logic over bytes (no Fast DDS types): one instance per participant, shared by its
// transports' receive threads and its listener; every member is thread-safe.

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <list>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace lb::ddsl {

using GuidPrefix = std::array<std::uint8_t, 12>;
std::string prefix_text(const GuidPrefix& prefix);  // "01.0f.45..." as Fast DDS prints one

struct GateLimits {
  // Pending participants holding a handshake message of this side (on an unsecured line: every
  // pending one); dds.max_pending_participants.
  int pending = 32;
  // Secured: pending participants this side only waits for (their handshake request): a proxy
  // each, nothing in the handshake history (Fast DDS still sends them its announcements).
  int waiting = 64;
  std::chrono::milliseconds prove_within{10'000};
  // A handshake under way is not cut for being slow (a crowd starting at once on a loaded machine:
  // up to 40 s to the last one's first sample with 100 at once).
  std::chrono::milliseconds talk_within{60'000};
  std::chrono::milliseconds replaceable_after{3'000};
  std::chrono::milliseconds refuse_for{30'000};
  // Fast DDS 2.9.1's participant stateless message history holds 100 changes.
  int handshake_slots = 96;
  // First sightings and evicted participants remembered (about 100 bytes each). A newcomer announcing
  // less often than the flood takes to pass this many gets in through its start's burst.
  std::size_t remember = 16384;
};

// What the gate has done since the participant started, and holds now.
struct GateCounts {
  std::uint64_t admitted = 0;           // participants let through pending
  std::uint64_t proven = 0;             // ... of which proved themselves
  std::uint64_t evicted = 0;            // pending participants removed unproven
  std::uint64_t dropped = 0;            // messages not handed to Fast DDS
  std::uint64_t unsecured_ignored = 0;  // announcements without an identity token (secured gate)
  std::uint64_t first_sightings = 0;    // announcements of participants not seen before (dropped)
  std::uint64_t waited = 0;             // announcements dropped because `pending` (or the slots) were full
  int pending_now = 0;
  int proven_now = 0;
  int handshake_slots_now = 0;  // secured: pending + authenticated whose handshake this side started
};

class DiscoveryGate {
 public:
  using Clock = std::chrono::steady_clock;
  enum class Proof { authentication, traffic };

  DiscoveryGate(Proof proof, GateLimits limits) : proof_(proof), limits_(limits) {}

  // The participant's own GUID prefix, once Fast DDS made it (a secured one derives it from its
  // certificate): its own messages pass, and which handshakes it starts depends on it.
  void set_local(const GuidPrefix& local);

  // A received RTPS message. Returns what to hand to Fast DDS: nothing (dropped), or the message,
  // in `rewritten` when a pending participant's announcement had its sequence number set (then
  // the returned span points into it).
  struct Verdict {
    bool pass = false;
    bool rewritten = false;     // hand Fast DDS `rewritten`, not the message
    bool announcement = false;  // it carried an SPDP announcement (the socket is a discovery one)
  };
  Verdict inspect(std::span<const std::uint8_t> message, std::vector<std::uint8_t>& rewritten, Clock::time_point now);

  // What to hand Fast DDS now, on a discovery socket, for the participants evicted or gone: for
  // each the announcement it was let in with, with a lease of 1 s (or, without one, its goodbye).
  std::vector<std::vector<std::uint8_t>> due(Clock::time_point now);
  // The unregister-dispose announcement of `prefix`, as its own participant would send it.
  static std::vector<std::uint8_t> goodbye(const GuidPrefix& prefix, std::uint32_t epoch);
  // The lease Fast DDS is given for a participant it must forget.
  static constexpr std::uint32_t kLastLeaseS = 1;
  // How long an evicted participant is kept out, and counted, if Fast DDS never reports it dropped
  // (it had no proxy for it): its lease of 1 s and Fast DDS's lease check, with room.
  static constexpr std::chrono::seconds kLeavingAtMost{5};
  // The announcement a participant was let in with, as it reached Fast DDS (an RTPS header and the
  // DATA submessage), to hand it again with its lease ended. Kept once: what its later
  // announcements change (locators, say) matters nothing to a participant Fast DDS drops a second
  // later, and copying each would cost an allocation per announcement.
  struct KeptAnnouncement {
    std::vector<std::uint8_t> message;
    std::size_t sn_at = 0;
    bool sn_little = true;
    std::size_t lease_at = 0;  // 0: it carried no lease
    bool lease_little = true;
  };

  // From the participant's discovery callbacks.
  void authenticated(const GuidPrefix& remote, Clock::time_point now);
  void refused(const GuidPrefix& remote, Clock::time_point now);  // failed authentication: evicted at once
  // Fast DDS forgot it (gone, lease).
  void departed(const GuidPrefix& remote, Clock::time_point now = Clock::now());

  GateCounts counts() const;
  // One line per new kind of event since the last call (evictions, waits), for a rate-limited log.
  std::vector<std::string> take_news();

 private:
  // leaving: evicted, its lease ended in Fast DDS, which drops it within about a second: it still
  // counts in the quotas (Fast DDS still holds it, and its handshake message), nothing of it passes.
  enum class State { pending, proven, refused, leaving };
  struct Entry {
    State state = State::pending;
    Clock::time_point admitted;
    Clock::time_point until;  // pending: evicted then; refused: dropped until then
    bool initiator = false;   // secured: this side starts (and keeps) the handshake
    std::uint32_t epoch = 0;  // the high word of its announcements' sequence numbers in Fast DDS
    bool talked = false;      // pending: it sent more than announcements (a handshake message)
    bool failed = false;      // its authentication failed
    KeptAnnouncement kept;    // empty message: none (authenticated without passing as pending)
  };
  struct PrefixHash {
    std::size_t operator()(const GuidPrefix& p) const noexcept;
  };

  using Iterator = std::unordered_map<GuidPrefix, Entry, PrefixHash>::iterator;
  bool initiates(const GuidPrefix& remote) const;
  bool engaged(const Entry& e) const;
  bool holds_message(const Entry& e) const;
  void count_nts(const Entry& e, int sign);  // the counters of e's state, +1 or -1
  void took_part_nts(Iterator it);
  void prove_nts(Iterator it);
  void leave_nts(Iterator it);
  void remember_nts(const GuidPrefix& prefix);
  bool seen_before_nts(const GuidPrefix& prefix);
  void evict_nts(Iterator it, Clock::time_point now);
  void left_nts(Iterator it, Clock::time_point now);  // a leaving one is gone from Fast DDS
  void forget_nts(const GuidPrefix& prefix, const KeptAnnouncement& kept);
  void trim_refused_nts(Clock::time_point now);
  bool room_nts(const Entry& e, Clock::time_point now);

  const Proof proof_;
  const GateLimits limits_;
  mutable std::mutex mutex_;
  std::optional<GuidPrefix> local_;
  std::unordered_map<GuidPrefix, Entry, PrefixHash> entries_;
  // First sightings, oldest first (bounded by limits_.remember).
  std::list<GuidPrefix> seen_order_;
  std::unordered_map<GuidPrefix, std::list<GuidPrefix>::iterator, PrefixHash> seen_;
  std::vector<std::vector<std::uint8_t>> to_hand_;                      // lease ends and goodbyes for due()
  std::list<GuidPrefix> refused_order_;                                 // oldest refusal first
  std::deque<std::pair<GuidPrefix, Clock::time_point>> pending_order_;  // admission order (stale ones skipped)
  // Epochs, one series for every participant (RTPS's high word is an int32: at ten participants let
  // in a second it lasts six years).
  std::uint32_t sequence_ = 0;
  Clock::time_point next_due_ = Clock::time_point::max();
  int pending_ = 0;  // pending and leaving
  int leaving_ = 0;
  int holding_ = 0;  // pending ones that hold a handshake message of this side (unsecured: all pending)
  int proven_ = 0;
  int proven_initiators_ = 0;
  int refused_ = 0;
  GateCounts counts_;
  std::uint64_t evicted_reported_ = 0, waited_reported_ = 0, unsecured_reported_ = 0, first_reported_ = 0;
};

}  // namespace lb::ddsl
