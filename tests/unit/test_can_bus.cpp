// The CAN layer against real sockets: URI parsing, the virtual bus (delivery, total order, hub
// hand-over, members in other processes, overrun reporting), the listen-only decorator, and
// SocketCAN's clean failure on a kernel without it.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <latch>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "can/detail.hpp"
#include "can/unique_fd.hpp"
#include "can/virtual_bus.hpp"
#include "can/virtual_bus_wire.hpp"

namespace lb::can {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// Unique per process and test, so parallel ctest runs never share a hub.
std::string bus_name() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return "t" + std::to_string(::getpid()) + "-" + info->test_suite_name() + "-" + info->name();
}

std::unique_ptr<Bus> must_open(const std::string& uri, BusAccess access = BusAccess::read_write) {
  auto bus = open_bus(uri, access);
  if (!bus) throw std::runtime_error(bus.error().message);
  return std::move(*bus);
}

std::unique_ptr<VirtualBus> must_open_virtual(const std::string& name) {
  auto bus = VirtualBus::open(name);
  if (!bus) throw std::runtime_error(bus.error().message);
  return std::move(*bus);
}

CanFrame seq_frame(std::uint32_t id, int seq) {
  return make_frame(id, {static_cast<std::uint8_t>(seq & 0xFF), static_cast<std::uint8_t>(seq >> 8)});
}
int seq_of(const CanFrame& f) { return f.data[0] | (f.data[1] << 8); }

int ms_until(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left > 0 ? static_cast<int>(left) : 0;
}

// The next frame, waiting on fd() as an event loop would; nullopt after the timeout.
std::optional<CanFrame> next_frame(Bus& bus, std::chrono::milliseconds timeout = 2000ms) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    auto r = bus.receive();
    if (!r) {
      ADD_FAILURE() << bus.uri() << ": " << r.error().message;
      return std::nullopt;
    }
    if (*r) return **r;
    if (Clock::now() >= deadline) return std::nullopt;
    pollfd p{bus.fd(), POLLIN, 0};
    ::poll(&p, 1, ms_until(deadline));
  }
}

// Every frame receive() has ready now, without waiting.
std::vector<CanFrame> drain(Bus& bus) {
  std::vector<CanFrame> frames;
  for (;;) {
    auto r = bus.receive();
    if (!r) {
      ADD_FAILURE() << bus.uri() << ": " << r.error().message;
      return frames;
    }
    if (!*r) return frames;
    frames.push_back(**r);
  }
}

// Retries while the transmit queue is full (the bus never waits, so the test does).
bool send_patiently(Bus& bus, const CanFrame& f, std::chrono::milliseconds timeout = 5000ms) {
  const auto deadline = Clock::now() + timeout;
  while (!bus.send(f)) {
    if (Clock::now() >= deadline) return false;
    std::this_thread::sleep_for(100us);
  }
  return true;
}

constexpr std::uint32_t kProbeB = 0x7E0, kProbeC = 0x7E1;

// After the hub went away, frames in the gap may be lost: probe until each of two members has heard
// the other once, waiting only on the event loop `loop` (which holds both fd()s). False after 2 s.
bool relink(Bus& b, Bus& c, int loop) {
  bool b_heard_c = false, c_heard_b = false;
  const auto deadline = Clock::now() + 2s;
  while (!(b_heard_c && c_heard_b) && Clock::now() < deadline) {
    (void)b.send(make_frame(kProbeB, {}));
    (void)c.send(make_frame(kProbeC, {}));
    epoll_event ev[2];
    ::epoll_wait(loop, ev, 2, 20);
    for (const CanFrame& f : drain(b)) b_heard_c |= f.id == kProbeC;
    for (const CanFrame& f : drain(c)) c_heard_b |= f.id == kProbeB;
  }
  return b_heard_c && c_heard_b;
}

UniqueFd event_loop_with(std::initializer_list<int> fds) {
  UniqueFd loop{::epoll_create1(EPOLL_CLOEXEC)};
  for (int fd : fds) {
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.fd = fd;
    if (::epoll_ctl(loop.get(), EPOLL_CTL_ADD, fd, &ev) != 0) throw std::runtime_error("epoll_ctl failed");
  }
  return loop;
}

// 100 frames from one member to another, none lost and in order (stray probes skipped).
void expect_stream(Bus& from, Bus& to, std::uint32_t id) {
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(send_patiently(from, seq_frame(id, i)));
  for (int i = 0; i < 100;) {
    auto f = next_frame(to);
    ASSERT_TRUE(f) << "frame " << i << " of " << id << " lost";
    if (f->id == kProbeB || f->id == kProbeC) continue;
    EXPECT_EQ(f->id, id);
    EXPECT_EQ(seq_of(*f), i);
    ++i;
  }
}

// -------------------------------------------------------------------------------------------------

TEST(OpenBus, RejectsMalformedUris) {
  struct Case {
    std::string uri;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"", "unknown scheme"},
      {"can0", "unknown scheme"},
      {"vcan:can0", "unknown scheme"},
      {"Virtual:demo", "unknown scheme"},
      {":demo", "unknown scheme"},
      {"virtual:", "empty"},
      {"socketcan:", "empty"},
      {"virtual:has space", "bus name"},
      {"virtual:" + std::string(92, 'x'), "bus name"},
      {"socketcan:" + std::string(16, 'x'), "interface name"},
  };
  for (const auto& c : cases) {
    auto bus = open_bus(c.uri);
    ASSERT_FALSE(bus) << "'" << c.uri << "' was accepted";
    EXPECT_NE(bus.error().message.find(c.says), std::string::npos) << "'" << c.uri << "': " << bus.error().message;
  }
}

TEST(OpenBus, VirtualUriRoundTrips) {
  const std::string uri = "virtual:" + bus_name();
  auto bus = must_open(uri);
  EXPECT_EQ(bus->uri(), uri);
  EXPECT_GE(bus->fd(), 0);
  auto r = bus->receive();
  ASSERT_TRUE(r);
  EXPECT_FALSE(*r);
}

TEST(VirtualBus, TwoMembersSeeEachOtherButNotThemselves) {
  const std::string uri = "virtual:" + bus_name();
  auto a = must_open(uri);
  auto b = must_open(uri);

  ASSERT_TRUE(a->send(make_frame(0x181, {0x11, 0x22})));
  auto fb = next_frame(*b);
  ASSERT_TRUE(fb);
  EXPECT_EQ(fb->id, 0x181u);
  ASSERT_EQ(fb->len, 2);
  EXPECT_EQ(fb->data[0], 0x11);
  EXPECT_EQ(fb->data[1], 0x22);

  // b got a's frame, so the hub has handled it; had it echoed it to a, that echo would come first.
  ASSERT_TRUE(b->send(make_frame(0x182, {0x33})));
  auto fa = next_frame(*a);
  ASSERT_TRUE(fa);
  EXPECT_EQ(fa->id, 0x182u);
  EXPECT_TRUE(drain(*a).empty());
  EXPECT_TRUE(drain(*b).empty());

  EXPECT_EQ(a->stats().frames_out, 1u);
  EXPECT_EQ(a->stats().frames_in, 1u);
  EXPECT_EQ(b->stats().frames_out, 1u);
  EXPECT_EQ(b->stats().frames_in, 1u);
}

TEST(VirtualBus, ThreeMembersCarryEveryKindOfFrame) {
  const std::string uri = "virtual:" + bus_name();
  std::vector<std::unique_ptr<Bus>> m;
  for (int i = 0; i < 3; ++i) m.push_back(must_open(uri));

  CanFrame ext = make_frame(0x1ABC'DEF0, {1, 2, 3, 4, 5, 6, 7, 8});
  ext.extended = true;
  CanFrame rtr = make_frame(0x7FF, {});
  rtr.rtr = true;
  rtr.len = 4;  // a remote request carries a DLC but no data
  const CanFrame empty = make_frame(0x000, {});
  const CanFrame sent[3] = {ext, rtr, empty};

  for (int s = 0; s < 3; ++s) {
    const std::int64_t before = detail::realtime_ns();
    ASSERT_TRUE(m[s]->send(sent[s]));
    for (int r = 0; r < 3; ++r) {
      if (r == s) continue;
      auto f = next_frame(*m[r]);
      ASSERT_TRUE(f) << "member " << r << " missed member " << s;
      EXPECT_EQ(f->id, sent[s].id);
      EXPECT_EQ(f->extended, sent[s].extended);
      EXPECT_EQ(f->rtr, sent[s].rtr);
      EXPECT_FALSE(f->error);
      EXPECT_EQ(f->len, sent[s].len);
      if (!f->rtr) {
        EXPECT_EQ(f->data, sent[s].data);
      }
      EXPECT_GE(f->timestamp_ns, before);
      EXPECT_LE(f->timestamp_ns, detail::realtime_ns());
    }
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(drain(*m[i]).empty()) << "member " << i;
    EXPECT_EQ(m[i]->stats().frames_out, 1u);
    EXPECT_EQ(m[i]->stats().frames_in, 2u);
    EXPECT_EQ(m[i]->stats().tx_dropped, 0u);
  }
}

TEST(VirtualBus, CarriesInjectedErrorFrames) {
  const std::string uri = "virtual:" + bus_name();
  auto a = must_open(uri);
  auto b = must_open(uri);
  CanFrame busoff = make_frame(CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  busoff.error = true;
  ASSERT_TRUE(a->send(busoff));
  auto f = next_frame(*b);
  ASSERT_TRUE(f);
  EXPECT_TRUE(f->error);
  EXPECT_EQ(f->id, CAN_ERR_BUSOFF);
  EXPECT_EQ(b->stats().error_frames, 1u);
  EXPECT_EQ(b->stats().frames_in, 0u);
}

TEST(VirtualBus, RefusesFramesNoControllerCouldSend) {
  const std::string uri = "virtual:" + bus_name();
  auto a = must_open(uri);
  CanFrame too_long = make_frame(0x100, {});
  too_long.len = 9;
  CanFrame wide_std = make_frame(0x800, {});
  CanFrame wide_ext = make_frame(0x2000'0000, {});
  wide_ext.extended = true;
  for (const CanFrame& f : {too_long, wide_std, wide_ext}) {
    auto r = a->send(f);
    ASSERT_FALSE(r);
    EXPECT_NE(r.error().message.find(uri), std::string::npos) << r.error().message;
  }
  EXPECT_EQ(a->stats().frames_out, 0u);
}

// Any local process can connect to a hub and send any bytes. Messages no member could have sent
// (an 11-bit identifier above 7FFh, a 29-bit one above 1FFFFFFFh, unknown flags, an error frame
// marked remote, more than 8 bytes) must not reach the members as frames: the layers above index
// tables by identifier. Before, only the length was checked.
TEST(VirtualBus, DropsWireMessagesNoMemberCouldHaveSent) {
  const std::string name = bus_name();
  auto a = must_open("virtual:" + name);
  lb::can::UniqueFd raw{::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0)};
  ASSERT_TRUE(raw);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string abstract = std::string(1, '\0') + "linebridge-vbus/" + name;
  std::memcpy(addr.sun_path, abstract.data(), abstract.size());
  ASSERT_EQ(::connect(raw.get(), reinterpret_cast<const sockaddr*>(&addr),
                      static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + abstract.size())),
            0);
  lb::can::wire::Msg welcome{};
  ASSERT_EQ(::recv(raw.get(), &welcome, sizeof welcome, 0), static_cast<ssize_t>(sizeof welcome));
  const auto message = [](std::uint32_t id, std::uint8_t flags, std::uint8_t len) {
    lb::can::wire::Msg m{};
    m.id = id;
    m.kind = lb::can::wire::Kind::frame;
    m.flags = flags;
    m.len = len;
    return m;
  };
  using lb::can::wire::kFlagError, lb::can::wire::kFlagExtended, lb::can::wire::kFlagRtr;
  for (const auto& m : {message(0x900, 0, 1), message(0x3000'0000, kFlagExtended, 1), message(0x100, 0x80, 1),
                        message(0x4, kFlagError | kFlagRtr, 8), message(0x100, 0, 9), message(0x123, 0, 1)}) {
    ASSERT_EQ(::send(raw.get(), &m, sizeof m, MSG_NOSIGNAL), static_cast<ssize_t>(sizeof m));
  }
  const auto f = next_frame(*a);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->id, 0x123u) << "a malformed message came through";
  EXPECT_FALSE(next_frame(*a, 200ms));
}

// Two senders send bursts at the same time from two threads; two receivers record what they see.
// Both must see the same sequence, with each sender's frames in the order it sent them.
TEST(VirtualBus, AllMembersSeeOneTotalOrder) {
  const std::string uri = "virtual:" + bus_name();
  auto s1 = must_open(uri);
  auto s2 = must_open(uri);
  auto r1 = must_open(uri);
  auto r2 = must_open(uri);
  constexpr int kPerSender = 1000;
  constexpr int kBurst = 100;  // well below a member's queue, so a busy machine drops nothing

  std::vector<std::uint32_t> log1, log2;
  auto record = [](Bus& bus, std::vector<std::uint32_t>& log) {
    for (const CanFrame& f : drain(bus)) log.push_back(f.error ? 0xFFFF'FFFF : (f.id << 16 | seq_of(f)));
  };
  for (int round = 0; round < kPerSender / kBurst; ++round) {
    std::latch start(2);
    auto burst = [round, &start](Bus& bus, std::uint32_t id) {
      start.arrive_and_wait();
      for (int i = round * kBurst; i < (round + 1) * kBurst; ++i) {
        // Short pauses spread each burst out so the two really overlap at the hub; without them
        // one sender usually finishes before the other has been scheduled.
        if (i % 5 == 0) std::this_thread::sleep_for(50us);
        if (!send_patiently(bus, seq_frame(id, i))) return;
        (void)drain(bus);  // the other sender's frames
      }
    };
    {
      std::jthread t1(burst, std::ref(*s1), 0x101u);
      std::jthread t2(burst, std::ref(*s2), 0x102u);
      const std::size_t want = 2u * kBurst * (round + 1);
      const auto deadline = Clock::now() + 20s;
      while ((log1.size() < want || log2.size() < want) && Clock::now() < deadline) {
        pollfd p[2] = {{r1->fd(), POLLIN, 0}, {r2->fd(), POLLIN, 0}};
        ::poll(p, 2, 100);
        record(*r1, log1);
        record(*r2, log2);
      }
    }
    ASSERT_EQ(log1.size(), 2u * kBurst * (round + 1)) << "round " << round;
    ASSERT_EQ(log2.size(), 2u * kBurst * (round + 1)) << "round " << round;
  }

  EXPECT_EQ(log1, log2);
  int switches = 0;  // how interleaved the order was, for the record
  for (std::size_t i = 1; i < log1.size(); ++i) switches += (log1[i] >> 16) != (log1[i - 1] >> 16);
  RecordProperty("sender_switches", switches);
  for (std::uint32_t id : {0x101u, 0x102u}) {
    int expect = 0;
    for (std::uint32_t key : log1) {
      if (key >> 16 != id) continue;
      EXPECT_EQ(static_cast<int>(key & 0xFFFF), expect) << "sender " << id;
      ++expect;
    }
    EXPECT_EQ(expect, kPerSender);
  }
  EXPECT_EQ(r1->stats().error_frames, 0u);
  EXPECT_EQ(r2->stats().error_frames, 0u);
}

TEST(VirtualBus, SurvivesTheLossOfTheHubOwner) {
  const std::string name = bus_name();
  auto a = must_open_virtual(name);
  auto b = must_open_virtual(name);
  auto c = must_open_virtual(name);
  ASSERT_TRUE(a->owns_hub());
  EXPECT_FALSE(b->owns_hub());
  EXPECT_FALSE(c->owns_hub());

  // The caller's event loop registers fd() once; it must keep working across the hand-over.
  const int b_fd = b->fd();
  const int c_fd = c->fd();
  const UniqueFd loop = event_loop_with({b_fd, c_fd});

  ASSERT_TRUE(b->send(make_frame(0x100, {})));
  ASSERT_TRUE(next_frame(*c));
  ASSERT_TRUE(next_frame(*a));

  a.reset();

  ASSERT_TRUE(relink(*b, *c, loop.get())) << "no working bus 2 s after the hub owner went away";
  EXPECT_NE(b->owns_hub(), c->owns_hub()) << "exactly one survivor must run the hub";
  EXPECT_EQ(b->fd(), b_fd);
  EXPECT_EQ(c->fd(), c_fd);
  expect_stream(*b, *c, 0x201);
  expect_stream(*c, *b, 0x202);
}

// The hub's process dies without any cleanup: the kernel closing its sockets is the only signal.
TEST(VirtualBus, SurvivesTheDeathOfTheHubProcess) {
  const std::string name = bus_name();
  int ready[2];
  int hold[2];
  ASSERT_EQ(::pipe2(ready, O_CLOEXEC), 0);
  ASSERT_EQ(::pipe2(hold, O_CLOEXEC), 0);
  // Forked before this process has any thread, so the child may start the hub thread.
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0) << std::strerror(errno);
  if (pid == 0) {
    ::close(ready[0]);
    ::close(hold[1]);
    auto bus = VirtualBus::open(name);
    const char verdict = bus && (*bus)->owns_hub() ? 'H' : 'x';
    if (::write(ready[1], &verdict, 1) != 1) ::_exit(2);
    char c;
    while (::read(hold[0], &c, 1) < 0 && errno == EINTR) {
    }
    ::_exit(0);
  }
  ::close(ready[1]);
  ::close(hold[0]);
  const UniqueFd ready_r{ready[0]};
  const UniqueFd hold_w{hold[1]};
  pollfd p{ready_r.get(), POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 5000), 1);
  char verdict = 0;
  ASSERT_EQ(::read(ready_r.get(), &verdict, 1), 1);
  ASSERT_EQ(verdict, 'H') << "the child did not become the hub";

  auto b = must_open_virtual(name);
  auto c = must_open_virtual(name);
  EXPECT_FALSE(b->owns_hub());
  ASSERT_TRUE(b->send(make_frame(0x100, {})));
  ASSERT_TRUE(next_frame(*c));

  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);

  const UniqueFd loop = event_loop_with({b->fd(), c->fd()});
  ASSERT_TRUE(relink(*b, *c, loop.get())) << "no working bus 2 s after the hub process died";
  EXPECT_NE(b->owns_hub(), c->owns_hub());
  expect_stream(*b, *c, 0x201);
  expect_stream(*c, *b, 0x202);
}

// Re-election also when the owner is destroyed while nobody is reading: the first send notices.
TEST(VirtualBus, SendAloneReelects) {
  const std::string name = bus_name();
  auto a = must_open_virtual(name);
  auto b = must_open_virtual(name);
  a.reset();
  const auto deadline = Clock::now() + 2s;
  while (!b->send(make_frame(0x100, {})) && Clock::now() < deadline) std::this_thread::sleep_for(5ms);
  EXPECT_TRUE(b->owns_hub());
  auto c = must_open_virtual(name);
  ASSERT_TRUE(b->send(make_frame(0x101, {})));
  // 0x100 may still be queued at the new hub when c joins, like a frame waiting in a TX queue.
  auto f = next_frame(*c);
  if (f && f->id == 0x100) f = next_frame(*c);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->id, 0x101u);
}

TEST(VirtualBus, MemberInAnotherProcess) {
  const std::string name = bus_name();
  auto parent = must_open_virtual(name);
  ASSERT_TRUE(parent->owns_hub());
  constexpr int kFrames = 200;

  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0) << std::strerror(errno);
  if (pid == 0) {
    // The child never returns into GoogleTest; its exit code is the verdict.
    int code = 0;
    {
      auto bus = VirtualBus::open(name);
      if (!bus) ::_exit(2);
      if ((*bus)->owns_hub()) ::_exit(3);
      for (int i = 0; i < kFrames && code == 0; ++i) {
        if (!send_patiently(**bus, seq_frame(0x301, i))) code = 4;
      }
    }
    ::_exit(code);
  }

  int got = 0;
  while (got < kFrames) {
    auto f = next_frame(*parent, 10s);
    if (!f) break;
    EXPECT_EQ(f->id, 0x301u);
    EXPECT_EQ(seq_of(*f), got);
    ++got;
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_EQ(got, kFrames);
}

// A member that does not read loses frames, never stalls the others, and is told by an RX overflow
// error frame placed where the gap is.
TEST(VirtualBus, SlowMemberGetsOverrunErrorFrame) {
  const std::string uri = "virtual:" + bus_name();
  auto fast = must_open(uri);
  auto slow = must_open(uri);
  constexpr int kFrames = 20000;  // several times what the kernel lets the hub queue for one member
  for (int i = 0; i < kFrames; ++i) ASSERT_TRUE(send_patiently(*fast, seq_frame(0x181, i)));

  // The notice goes out with the next frame the slow member has room for: keep offering a marker.
  constexpr std::uint32_t kMarker = 0x7FF;
  bool overflow_seen = false, marker_seen = false;
  int frames = 0, last_seq = -1;
  const auto deadline = Clock::now() + 10s;
  while (!marker_seen && Clock::now() < deadline) {
    (void)fast->send(make_frame(kMarker, {}));
    auto f = next_frame(*slow, 50ms);
    for (; f; f = next_frame(*slow, 0ms)) {
      if (f->error) {
        EXPECT_EQ(f->id, CAN_ERR_CRTL);
        EXPECT_EQ(f->data[1] & CAN_ERR_CRTL_RX_OVERFLOW, CAN_ERR_CRTL_RX_OVERFLOW);
        overflow_seen = true;
      } else if (f->id == kMarker) {
        EXPECT_TRUE(overflow_seen) << "the overrun notice must come before frames after the gap";
        marker_seen = true;
      } else {
        EXPECT_GT(seq_of(*f), last_seq);
        last_seq = seq_of(*f);
        ++frames;
      }
    }
  }
  EXPECT_TRUE(marker_seen);
  EXPECT_TRUE(overflow_seen);
  EXPECT_GT(frames, 0);
  EXPECT_LT(frames, kFrames);
  EXPECT_GE(slow->stats().error_frames, 1u);
}

TEST(ListenOnlyBus, RefusesToSendAndCountsIt) {
  const std::string uri = "virtual:" + bus_name();
  auto monitor = must_open(uri, BusAccess::listen_only);
  auto node = must_open(uri);
  auto other = must_open(uri);
  EXPECT_EQ(monitor->uri(), uri);

  ASSERT_TRUE(node->send(make_frame(0x181, {0x42})));
  auto seen = next_frame(*monitor);
  ASSERT_TRUE(seen);
  EXPECT_EQ(seen->id, 0x181u);
  ASSERT_TRUE(next_frame(*other));

  auto r = monitor->send(make_frame(0x201, {0x01}));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().message, "bus " + uri + " is listen-only (monitor role): transmission refused");
  EXPECT_EQ(monitor->stats().tx_dropped, 1u);
  EXPECT_EQ(monitor->stats().frames_out, 0u);
  EXPECT_EQ(monitor->stats().frames_in, 1u);

  // Nothing reached the bus: the next frame node sees is other's, not the refused one.
  ASSERT_TRUE(other->send(make_frame(0x7FF, {})));
  auto next = next_frame(*node);
  ASSERT_TRUE(next);
  EXPECT_EQ(next->id, 0x7FFu);
}

bool kernel_has_socketcan() {
  UniqueFd probe{::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW)};
  return static_cast<bool>(probe);
}

TEST(SocketCanBus, FailsCleanlyWithoutKernelSupport) {
  if (kernel_has_socketcan()) GTEST_SKIP() << "this kernel has SocketCAN; tests/socketcan covers the real thing";
  auto bus = open_bus("socketcan:vcan0");
  ASSERT_FALSE(bus);
  EXPECT_NE(bus.error().message.find("no SocketCAN"), std::string::npos) << bus.error().message;
  auto monitor = open_bus("socketcan:vcan0", BusAccess::listen_only);
  EXPECT_FALSE(monitor);
}

TEST(SocketCanBus, MissingInterfaceIsAnError) {
  // Whatever this kernel has, an interface that does not exist cannot be opened.
  auto bus = open_bus("socketcan:lbnosuchcan0");
  ASSERT_FALSE(bus);
  EXPECT_NE(bus.error().message.find("socketcan:lbnosuchcan0"), std::string::npos) << bus.error().message;
}

}  // namespace
}  // namespace lb::can
