#include "dds/discovery_gate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

namespace lb::ddsl {
namespace {

// RTPS 2.x (OMG DDSI-RTPS 2.3, 9.4): what the gate needs of a message.
constexpr std::size_t kHeaderSize = 20;  // "RTPS", version, vendor, GUID prefix
constexpr std::uint8_t kPad = 0x01, kInfoTs = 0x09, kInfoSrc = 0x0c, kInfoDst = 0x0e, kData = 0x15, kDataFrag = 0x16;
constexpr std::uint8_t kVendorSpecific = 0x80;  // 0x80..0xff
constexpr std::uint8_t kFlagLittle = 0x01, kFlagInlineQos = 0x02, kFlagData = 0x04, kFlagKey = 0x08;
constexpr std::array<std::uint8_t, 4> kSpdpWriter{0x00, 0x01, 0x00, 0xc2};
constexpr std::array<std::uint8_t, 4> kSpdpReader{0x00, 0x01, 0x00, 0xc7};
constexpr std::array<std::uint8_t, 4> kParticipantEntity{0x00, 0x00, 0x01, 0xc1};
constexpr std::uint16_t kPidSentinel = 0x0001, kPidLeaseDuration = 0x0002, kPidParticipantGuid = 0x0050,
                        kPidBuiltinEndpoints = 0x0058, kPidKeyHash = 0x0070, kPidStatusInfo = 0x0071,
                        kPidIdentityToken = 0x1001;
constexpr std::uint32_t kParticipantAnnouncer = 0x00000001;  // DISC_BUILTIN_ENDPOINT_PARTICIPANT_ANNOUNCER

using Bytes = std::span<const std::uint8_t>;

std::uint16_t u16(Bytes b, std::size_t at, bool little) {
  return static_cast<std::uint16_t>(little ? (b[at] | (b[at + 1] << 8)) : ((b[at] << 8) | b[at + 1]));
}
std::uint32_t u32(Bytes b, std::size_t at, bool little) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v |= std::uint32_t{b[at + (little ? i : 3 - i)]} << (8 * i);
  return v;
}
GuidPrefix prefix_at(Bytes b, std::size_t at) {
  GuidPrefix p{};
  std::copy_n(b.begin() + static_cast<long>(at), p.size(), p.begin());
  return p;
}

// A parameter list from `at` to `end`: visit(pid, value offset, value length) for each parameter
// until the sentinel. False when it runs past `end` without one.
template <class Visit>
bool walk_parameters(Bytes b, std::size_t at, std::size_t end, bool little, std::size_t* after, Visit&& visit) {
  while (at + 4 <= end) {
    const auto pid = u16(b, at, little);
    const auto length = u16(b, at + 2, little);
    if (pid == kPidSentinel) {
      if (after != nullptr) *after = at + 4;
      return true;
    }
    if (at + 4 + length > end) return false;
    visit(static_cast<std::uint16_t>(pid & 0x3fff), at + 4, std::size_t{length});
    at += 4 + length;
  }
  return false;
}

struct Announcement {
  GuidPrefix participant{};
  bool alive = true;
  bool identity_token = false;
  bool announcer = false;  // its announcement writer is among its built-in endpoints
  std::size_t sn_at = 0;   // the writerSN's offset in the message
  bool little = true;
  std::size_t sub_at = 0, sub_end = 0;  // its DATA submessage in the message
  std::size_t lease_at = 0;             // its lease's offset (Duration_t: seconds, fraction), 0: none
  bool lease_little = true;
};

// The submessages of one source (the header's prefix, or an INFO_SRC's).
struct FromSource {
  GuidPrefix source{};
  bool other_traffic = false;  // anything but announcements and INFO_*/PAD
  std::vector<Announcement> announcements;
  std::vector<std::pair<std::size_t, bool>> fragments;  // an announcement's DATA_FRAGs: writerSN offset, little-endian
};

// The message's sources and their announcements; nothing for a message that is not RTPS or
// whose submessages do not add up (Fast DDS would stop reading it there too).
std::optional<std::vector<FromSource>> read_message(Bytes b) {
  if (b.size() < kHeaderSize || std::memcmp(b.data(), "RTPS", 4) != 0) return std::nullopt;
  std::vector<FromSource> out;
  out.push_back({prefix_at(b, 8), false, {}, {}});
  std::size_t at = kHeaderSize;
  while (at + 4 <= b.size()) {
    const std::uint8_t id = b[at];
    const std::uint8_t flags = b[at + 1];
    const bool little = (flags & kFlagLittle) != 0;
    const std::size_t length = u16(b, at + 2, little);
    const std::size_t body = at + 4;
    // Length 0: the submessage extends to the end of the message (except PAD and INFO_TS).
    const bool to_end = length == 0 && id != kPad && id != kInfoTs;
    const std::size_t end = to_end ? b.size() : body + length;
    if (end > b.size()) return std::nullopt;
    auto& from = out.back();
    if (id == kInfoSrc) {
      if (body + 20 > end) return std::nullopt;
      out.push_back({prefix_at(b, body + 8), false, {}, {}});
    } else if (id == kData || id == kDataFrag) {
      // extraFlags(2) octetsToInlineQos(2) readerId(4) writerId(4) writerSN(8)
      if (body + 20 > end) return std::nullopt;
      const bool spdp = std::equal(kSpdpWriter.begin(), kSpdpWriter.end(), b.begin() + static_cast<long>(body + 8));
      if (!spdp) {
        from.other_traffic = true;
      } else if (id == kDataFrag) {
        from.fragments.emplace_back(body + 12, little);
      } else {
        Announcement a;
        a.sn_at = body + 12;
        a.little = little;
        a.sub_at = at;
        a.sub_end = end;
        std::size_t p = body + 4 + u16(b, body + 2, little);
        if (p > end) return std::nullopt;
        bool have_guid = false;
        if ((flags & kFlagInlineQos) != 0) {
          const bool ok = walk_parameters(b, p, end, little, &p, [&](std::uint16_t pid, std::size_t v, std::size_t n) {
            if (pid == kPidKeyHash && n >= 16 && !have_guid) {
              a.participant = prefix_at(b, v);
              have_guid = true;
            }
            if (pid == kPidStatusInfo && n >= 4 && (b[v + 3] & 0x03) != 0) a.alive = false;
          });
          if (!ok) return std::nullopt;
        }
        if ((flags & (kFlagData | kFlagKey)) != 0 && p + 4 <= end) {
          // Encapsulation: PL_CDR_BE 0x0002, PL_CDR_LE 0x0003.
          const bool payload_little = b[p + 1] == 0x03;
          walk_parameters(b, p + 4, end, payload_little, nullptr, [&](std::uint16_t pid, std::size_t v, std::size_t n) {
            if (pid == kPidParticipantGuid && n >= 16) {
              // The payload names the participant Fast DDS keeps (PDPListener takes its GUID from here).
              a.participant = prefix_at(b, v);
              have_guid = true;
            }
            if (pid == kPidIdentityToken) a.identity_token = true;
            if (pid == kPidLeaseDuration && n >= 8) {
              a.lease_at = v;
              a.lease_little = payload_little;
            }
            if (pid == kPidBuiltinEndpoints && n >= 4 && (u32(b, v, payload_little) & kParticipantAnnouncer) != 0)
              a.announcer = true;
          });
        }
        if (!have_guid) return std::nullopt;
        from.announcements.push_back(a);
      }
    } else if (id != kPad && id != kInfoTs && id != kInfoDst && id < kVendorSpecific) {
      // Vendor-specific submessages are not taking part: Fast DDS 2.9 (built with its statistics,
      // as Debian's is) appends one (0x80) to every message, its announcements included.
      from.other_traffic = true;
    }
    if (to_end) break;
    at = end;
  }
  return out;
}

// A writerSN's high word (RTPS SequenceNumber_t: high int32, then low uint32), or any 32-bit word.
void write_high(std::vector<std::uint8_t>& m, std::size_t at, bool little, std::uint32_t high) {
  for (std::size_t i = 0; i < 4; ++i) m[at + (little ? i : 3 - i)] = static_cast<std::uint8_t>(high >> (8 * i));
}

// The announcement `a` of `source` alone in a message, as Fast DDS gets it (the sequence number's
// high word the gate's `epoch`).
DiscoveryGate::KeptAnnouncement keep(Bytes message, const GuidPrefix& source, const Announcement& a,
                                     std::uint32_t epoch) {
  DiscoveryGate::KeptAnnouncement k;
  auto& m = k.message;
  m.assign(message.begin(), message.begin() + 8);  // "RTPS", protocol version, vendor
  m.insert(m.end(), source.begin(), source.end());
  m.insert(m.end(), message.begin() + static_cast<long>(a.sub_at), message.begin() + static_cast<long>(a.sub_end));
  k.sn_at = kHeaderSize + (a.sn_at - a.sub_at);
  k.sn_little = a.little;
  if (a.lease_at != 0) k.lease_at = kHeaderSize + (a.lease_at - a.sub_at);
  k.lease_little = a.lease_little;
  write_high(m, k.sn_at, k.sn_little, epoch);
  return k;
}

}  // namespace

std::string prefix_text(const GuidPrefix& prefix) {
  std::string s;
  for (std::size_t i = 0; i < prefix.size(); ++i) s += fmt::format("{}{:02x}", i == 0 ? "" : ".", prefix[i]);
  return s;
}

std::size_t DiscoveryGate::PrefixHash::operator()(const GuidPrefix& p) const noexcept {
  std::uint64_t h = 14695981039346656037ULL;
  for (const auto byte : p) h = (h ^ byte) * 1099511628211ULL;
  return static_cast<std::size_t>(h);
}

void DiscoveryGate::set_local(const GuidPrefix& local) {
  std::lock_guard lock(mutex_);
  local_ = local;
  // Its own announcements, looped back before Fast DDS made its prefix known, are no remote participant.
  if (auto it = entries_.find(local); it != entries_.end()) leave_nts(it);
  if (auto it = seen_.find(local); it != seen_.end()) {
    seen_order_.erase(it->second);
    seen_.erase(it);
  }
  // Which handshakes this side starts was assumed (all) until now.
  pending_ = leaving_ = holding_ = proven_ = proven_initiators_ = refused_ = 0;
  for (auto& [prefix, e] : entries_) {
    e.initiator = initiates(prefix);
    count_nts(e, +1);
  }
}

bool DiscoveryGate::initiates(const GuidPrefix& remote) const {
  // PKI-DH: the participant with the smaller GUID sends the request, and keeps its final message
  // (PKIDH::validate_remote_identity compares the prefixes as bytes). Unknown: assume the worst.
  return !local_ || std::memcmp(local_->data(), remote.data(), remote.size()) < 0;
}

DiscoveryGate::Verdict DiscoveryGate::inspect(std::span<const std::uint8_t> message,
                                              std::vector<std::uint8_t>& rewritten, Clock::time_point now) {
  Verdict v;
  const auto sources = read_message(message);
  std::lock_guard lock(mutex_);
  if (!sources) {
    ++counts_.dropped;
    return v;
  }
  struct Rewrite {
    std::size_t at;
    bool little;
    std::uint32_t epoch;
  };
  std::vector<Rewrite> rewrites;
  bool pass = true;
  for (const auto& from : *sources) {
    v.announcement = v.announcement || !from.announcements.empty();
    if (local_ && from.source == *local_) continue;
    // An announcement names the participant it is sent by, in a message of that participant: Fast
    // DDS keeps the one the payload names, the gate decides by the message's source.
    const bool foreign = std::any_of(from.announcements.begin(), from.announcements.end(),
                                     [&](const Announcement& a) { return a.participant != from.source; });
    if (foreign) {
      pass = false;
      continue;
    }
    auto it = entries_.find(from.source);
    if (it != entries_.end() && it->second.state == State::leaving) {
      pass = false;
      continue;
    }
    if (it != entries_.end() && it->second.state == State::refused) {
      if (now < it->second.until) {
        pass = false;
        continue;
      }
      leave_nts(it);
      it = entries_.end();
    }
    if (it != entries_.end()) {
      const bool pending = it->second.state == State::pending;
      if (pending && !from.fragments.empty()) {  // a pending participant's announcement fits a message
        pass = false;
        continue;
      }
      // Its own goodbye: its lease ends instead (the header says why), unless it never gave one.
      const bool leaving = std::any_of(from.announcements.begin(), from.announcements.end(),
                                       [](const Announcement& a) { return !a.alive; });
      if (leaving && it->second.kept.lease_at != 0) {
        forget_nts(it->first, it->second.kept);
        pass = false;
        continue;
      }
      for (const auto& a : from.announcements) rewrites.push_back({a.sn_at, a.little, it->second.epoch});
      for (const auto& [at, little] : from.fragments) rewrites.push_back({at, little, it->second.epoch});
      if (pending && from.other_traffic) took_part_nts(it);
      continue;
    }
    // Not let in yet: only its own announcement can open the gate.
    const auto alive = std::find_if(from.announcements.begin(), from.announcements.end(),
                                    [](const Announcement& a) { return a.alive; });
    if (alive == from.announcements.end() || !from.fragments.empty()) {
      pass = false;
      continue;
    }
    if (proof_ == Proof::authentication && !alive->identity_token) {
      ++counts_.unsecured_ignored;
      pass = false;
      continue;
    }
    // A secured participant must be forgotten by its lease ending, never by a goodbye: no lease, no entry
    // (Fast DDS always announces one).
    if (proof_ == Proof::authentication && alive->lease_at == 0) {
      pass = false;
      continue;
    }
    // Without its announcement writer among its endpoints Fast DDS would not take its goodbye.
    if (!alive->announcer || !seen_before_nts(from.source)) {
      if (alive->announcer) remember_nts(from.source);
      ++counts_.first_sightings;
      pass = false;
      continue;
    }
    Entry e;
    e.state = State::pending;
    e.admitted = now;
    e.initiator = initiates(from.source);
    e.until = now + (engaged(e) ? limits_.talk_within : limits_.prove_within);
    if (!room_nts(e, now)) {
      ++counts_.waited;
      pass = false;
      continue;
    }
    if (auto s = seen_.find(from.source); s != seen_.end()) {
      seen_order_.erase(s->second);
      seen_.erase(s);
    }
    e.epoch = ++sequence_;
    e.kept = keep(message, from.source, *alive, e.epoch);
    const auto added = entries_.emplace(from.source, std::move(e)).first;
    count_nts(added->second, +1);
    pending_order_.emplace_back(from.source, now);
    ++counts_.admitted;
    next_due_ = std::min(next_due_, added->second.until);
    for (const auto& a : from.announcements) rewrites.push_back({a.sn_at, a.little, added->second.epoch});
    if (from.other_traffic) took_part_nts(added);
  }
  if (!pass) {
    ++counts_.dropped;
    return v;
  }
  v.pass = true;
  if (!rewrites.empty()) {
    rewritten.assign(message.begin(), message.end());
    for (const auto& r : rewrites) write_high(rewritten, r.at, r.little, r.epoch);
    v.rewritten = true;
  }
  return v;
}

std::vector<std::vector<std::uint8_t>> DiscoveryGate::due(Clock::time_point now) {
  std::lock_guard lock(mutex_);
  if (now >= next_due_) {
    next_due_ = Clock::time_point::max();
    std::vector<GuidPrefix> late;
    std::vector<GuidPrefix> gone;  // leaving ones Fast DDS never reported dropped
    for (const auto& [prefix, e] : entries_) {
      if (e.state != State::pending && e.state != State::leaving) continue;
      if (e.until <= now) {
        (e.state == State::pending ? late : gone).push_back(prefix);
      } else {
        next_due_ = std::min(next_due_, e.until);
      }
    }
    for (const auto& prefix : late) evict_nts(entries_.find(prefix), now);
    for (const auto& prefix : gone) left_nts(entries_.find(prefix), now);
    trim_refused_nts(now);
    while (!pending_order_.empty()) {
      const auto it = entries_.find(pending_order_.front().first);
      if (it != entries_.end() && it->second.state == State::pending &&
          it->second.admitted == pending_order_.front().second)
        break;
      pending_order_.pop_front();
    }
  }
  std::vector<std::vector<std::uint8_t>> out;
  out.swap(to_hand_);
  return out;
}

std::vector<std::uint8_t> DiscoveryGate::goodbye(const GuidPrefix& prefix, std::uint32_t epoch) {
  std::vector<std::uint8_t> m{'R', 'T', 'P', 'S', 2, 3, 0x01, 0x0f};
  m.insert(m.end(), prefix.begin(), prefix.end());
  const auto le16 = [&m](std::uint16_t v) {
    m.push_back(static_cast<std::uint8_t>(v));
    m.push_back(static_cast<std::uint8_t>(v >> 8));
  };
  // DATA, little-endian, inline QoS only: key hash and status "disposed, unregistered".
  m.push_back(kData);
  m.push_back(kFlagLittle | kFlagInlineQos);
  le16(20 + 20 + 8 + 4);
  le16(0);   // extraFlags
  le16(16);  // octetsToInlineQos
  m.insert(m.end(), kSpdpReader.begin(), kSpdpReader.end());
  m.insert(m.end(), kSpdpWriter.begin(), kSpdpWriter.end());
  const auto sn_at = m.size();
  m.resize(m.size() + 8);  // low word 0: above any number of an earlier epoch
  write_high(m, sn_at, true, epoch);
  le16(kPidKeyHash);
  le16(16);
  m.insert(m.end(), prefix.begin(), prefix.end());
  m.insert(m.end(), kParticipantEntity.begin(), kParticipantEntity.end());
  le16(kPidStatusInfo);
  le16(4);
  m.insert(m.end(), {0x00, 0x00, 0x00, 0x03});
  le16(kPidSentinel);
  le16(0);
  return m;
}

void DiscoveryGate::authenticated(const GuidPrefix& remote, Clock::time_point) {
  std::lock_guard lock(mutex_);
  if (local_ && remote == *local_) return;
  auto it = entries_.find(remote);
  if (it == entries_.end()) {
    // Authenticated without passing the gate as pending (it cannot: a participant Fast DDS
    // authenticates was let through), kept as proven so its messages keep passing.
    Entry e;
    e.state = State::proven;
    e.initiator = initiates(remote);
    e.epoch = ++sequence_;
    count_nts(entries_.emplace(remote, e).first->second, +1);
    return;
  }
  if (it->second.state != State::pending) return;
  prove_nts(it);
}

void DiscoveryGate::refused(const GuidPrefix& remote, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(remote);
  if (it == entries_.end() || it->second.state != State::pending) return;
  it->second.failed = true;
  evict_nts(it, now);
}

void DiscoveryGate::departed(const GuidPrefix& remote, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(remote);
  if (it == entries_.end() || it->second.state == State::refused) return;
  if (it->second.state == State::leaving) return left_nts(it, now);
  leave_nts(it);
}

void DiscoveryGate::count_nts(const Entry& e, int sign) {
  switch (e.state) {
    case State::pending:
      pending_ += sign;
      if (holds_message(e)) holding_ += sign;
      break;
    case State::proven:
      proven_ += sign;
      if (proof_ == Proof::authentication && e.initiator) proven_initiators_ += sign;
      break;
    case State::refused: refused_ += sign; break;
    case State::leaving:
      pending_ += sign;
      leaving_ += sign;
      if (holds_message(e)) holding_ += sign;
      break;
  }
}

bool DiscoveryGate::engaged(const Entry& e) const {
  // Secured, this side sent it a handshake message (its request, or its reply to one). Forgetting
  // it then could leave a real one stuck: Fast DDS 2.9.1 answers a new request of a participant it
  // sent a reply to with that old reply, which the new handshake ignores, until its lease ends.
  return proof_ == Proof::authentication && (e.initiator || e.talked);
}

bool DiscoveryGate::holds_message(const Entry& e) const {
  // Secured: this side sent a handshake message it keeps until the handshake ends (its request,
  // or its reply to one). Unsecured: every pending participant counts alike.
  return proof_ == Proof::traffic || e.initiator || e.talked;
}

void DiscoveryGate::took_part_nts(Iterator it) {
  if (proof_ == Proof::traffic) return prove_nts(it);
  if (it->second.talked) return;
  // In its handshake: it holds this side's reply, and gets the longer deadline.
  count_nts(it->second, -1);
  it->second.talked = true;
  it->second.until = it->second.admitted + limits_.talk_within;
  count_nts(it->second, +1);
  next_due_ = std::min(next_due_, it->second.until);
}

void DiscoveryGate::prove_nts(Iterator it) {
  count_nts(it->second, -1);
  it->second.state = State::proven;
  count_nts(it->second, +1);
  ++counts_.proven;
}

void DiscoveryGate::leave_nts(Iterator it) {
  count_nts(it->second, -1);
  entries_.erase(it);
}

void DiscoveryGate::evict_nts(std::unordered_map<GuidPrefix, Entry, PrefixHash>::iterator it, Clock::time_point now) {
  ++counts_.evicted;
  forget_nts(it->first, it->second.kept);
  // Fast DDS drops it about a second from now (its lease); until then it keeps what it held for
  // it, so it keeps its place in the quotas, and nothing of it passes (which would renew that lease).
  count_nts(it->second, -1);
  it->second.state = State::leaving;
  it->second.until = now + kLeavingAtMost;
  count_nts(it->second, +1);
  next_due_ = std::min(next_due_, it->second.until);
}

void DiscoveryGate::left_nts(Iterator it, Clock::time_point now) {
  if (!it->second.talked && !it->second.failed) {
    // It never answered: forged, or a real one its own gate kept waiting (a crowd starting at
    // once). Nothing is gained by keeping it out: a forger takes a new prefix anyway. Remembered,
    // it may come in again at its next announcement, as a newcomer.
    const auto prefix = it->first;
    leave_nts(it);
    remember_nts(prefix);
    return;
  }
  // It took part and did not authenticate (a certificate of another PKI, a revoked one): no new
  // handshake with it for a while.
  count_nts(it->second, -1);
  it->second.state = State::refused;
  it->second.until = now + limits_.refuse_for;
  count_nts(it->second, +1);
  refused_order_.push_back(it->first);
}

void DiscoveryGate::forget_nts(const GuidPrefix& prefix, const KeptAnnouncement& kept) {
  if (kept.lease_at == 0) {
    to_hand_.push_back(goodbye(prefix, ++sequence_));
    return;
  }
  auto m = kept.message;
  write_high(m, kept.sn_at, kept.sn_little, ++sequence_);
  write_high(m, kept.lease_at, kept.lease_little, kLastLeaseS);
  write_high(m, kept.lease_at + 4, kept.lease_little, 0);  // fraction
  to_hand_.push_back(std::move(m));
}

bool DiscoveryGate::room_nts(const Entry& e, Clock::time_point now) {
  // Two quotas: pending participants that hold a handshake message of this side (`pending`, and
  // every one on an unsecured line), and on a secured line those this side only waits for (their
  // request, `waiting`: a proxy each, nothing sent). Fast DDS's handshake history bounds the first.
  const bool holding = holds_message(e);
  const auto full = [&] {
    if (!holding) return pending_ - holding_ >= limits_.waiting;
    return holding_ >= limits_.pending ||
           (proof_ == Proof::authentication && holding_ + proven_initiators_ + 1 > limits_.handshake_slots);
  };
  if (!full()) return true;
  // The longest pending one of the same kind that this side sent nothing to and that sent nothing
  // but announcements goes, once it had `replaceable_after` to start its handshake: a quota filled
  // by forged participants then keeps a real newcomer out no longer than that, and no handshake
  // under way is cut (engaged()). Those holding a message of this side are all engaged: a newcomer
  // of that kind waits for one to authenticate, leave or reach its deadline.
  for (auto at = pending_order_.begin(); at != pending_order_.end();) {
    auto it = entries_.find(at->first);
    if (it == entries_.end() || it->second.state != State::pending || it->second.admitted != at->second) {
      at = pending_order_.erase(at);  // proven, evicted or gone since
      continue;
    }
    if (now < at->second + limits_.replaceable_after) return false;  // the rest are younger
    if (engaged(it->second) || it->second.talked || holds_message(it->second) != holding) {
      ++at;
      continue;
    }
    pending_order_.erase(at);
    evict_nts(it, now);
    return !full();
  }
  return false;
}

void DiscoveryGate::trim_refused_nts(Clock::time_point now) {
  // Oldest first (every refusal lasts as long): expired ones go, and beyond `remember` the oldest.
  while (!refused_order_.empty()) {
    auto it = entries_.find(refused_order_.front());
    const bool stale = it == entries_.end() || it->second.state != State::refused;
    if (!stale && it->second.until > now && static_cast<std::size_t>(refused_) <= limits_.remember) break;
    if (!stale) leave_nts(it);
    refused_order_.pop_front();
  }
}

void DiscoveryGate::remember_nts(const GuidPrefix& prefix) {
  if (seen_.count(prefix) != 0) return;
  if (seen_.size() >= limits_.remember) {
    seen_.erase(seen_order_.front());
    seen_order_.pop_front();
  }
  seen_order_.push_back(prefix);
  seen_[prefix] = std::prev(seen_order_.end());
}

bool DiscoveryGate::seen_before_nts(const GuidPrefix& prefix) { return seen_.count(prefix) != 0; }

GateCounts DiscoveryGate::counts() const {
  std::lock_guard lock(mutex_);
  GateCounts c = counts_;
  c.pending_now = pending_ - leaving_;
  c.proven_now = proven_;
  c.handshake_slots_now = proof_ == Proof::authentication ? holding_ + proven_initiators_ : 0;
  return c;
}

std::vector<std::string> DiscoveryGate::take_news() {
  std::lock_guard lock(mutex_);
  std::vector<std::string> news;
  if (counts_.evicted > evicted_reported_) {
    const auto n = counts_.evicted - evicted_reported_;
    if (proof_ == Proof::authentication) {
      news.push_back(
          fmt::format("{} remote participant(s) let in did not authenticate within {} s ({} s once a handshake "
                      "was under way) or failed to: forgotten (forged announcements?); {} pending now, at most {}",
                      n, limits_.prove_within.count() / 1000, limits_.talk_within.count() / 1000, pending_,
                      limits_.pending));
    } else {
      news.push_back(
          fmt::format("{} remote participant(s) let in did not take part in discovery within {} s: forgotten "
                      "(forged announcements?); {} pending now, at most {}",
                      n, limits_.prove_within.count() / 1000, pending_, limits_.pending));
    }
    evicted_reported_ = counts_.evicted;
  }
  if (counts_.waited > waited_reported_) {
    news.push_back(fmt::format(
        "{} announcement(s) of new participants dropped: {} pending participants at most{} (a flood of forged "
        "announcements, or more participants starting at once than that: they get in at a later announcement)",
        counts_.waited - waited_reported_, limits_.pending,
        proof_ == Proof::authentication
            ? fmt::format(", and {} handshakes held at most (Fast DDS 2.9.1 keeps one per authenticated participant "
                          "whose handshake this side started; {} now)",
                          limits_.handshake_slots, holding_ + proven_initiators_)
            : std::string()));
    waited_reported_ = counts_.waited;
  }
  if (counts_.first_sightings > first_reported_) {
    news.push_back(fmt::format("{} announcement(s) of participants not seen before dropped (a real participant "
                               "announces again within a second and gets in then; a forged one sent once never does)",
                               counts_.first_sightings - first_reported_));
    first_reported_ = counts_.first_sightings;
  }
  if (counts_.unsecured_ignored > unsecured_reported_) {
    news.push_back(fmt::format("{} announcement(s) without DDS Security identity ignored (unsecured participants on "
                               "this secured line's domain: they can never join it)",
                               counts_.unsecured_ignored - unsecured_reported_));
    unsecured_reported_ = counts_.unsecured_ignored;
  }
  return news;
}

}  // namespace lb::ddsl
