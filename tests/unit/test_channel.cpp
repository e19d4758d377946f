// The channel between a line's bus process and its DDS process, on real Unix sockets: its
// messages, who may connect (tests that need other users fork a child that becomes one: root
// only), what a (re)connecting DDS side is sent, lanes that die with their connection, the alarm
// without a DDS side, and that the bus side's publish never waits for a DDS side that does not read.
#include <grp.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "link/bus_channel.hpp"
#include "link/channel_message.hpp"
#include "link/dds_channel.hpp"

using namespace std::chrono_literals;
using namespace lb::link;

namespace {

std::string socket_path(const std::string& name) {
  return ::testing::TempDir() + "/lb_channel_" + name + "_" + std::to_string(::getpid()) + ".sock";
}

// The first message of kind T within 20 s. Pings (the bus side sends one every second) are skipped;
// any other message before it fails the wait unless skip_others.
template <class T>
T receive_first(DdsChannel& c, bool skip_others) {
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    auto m = c.receive(200);
    if (!m) throw std::runtime_error(m.error().message);
    if (!*m) continue;
    if (auto* t = std::get_if<T>(&**m)) return *t;
    if (!skip_others && !std::holds_alternative<Ping>(**m)) {
      throw std::runtime_error("another message came first (index " + std::to_string((*m)->index()) + ")");
    }
  }
  throw std::runtime_error("no such message within 20 s");
}

// The next message of a kind, skipping pings.
template <class T>
T next(DdsChannel& c) {
  return receive_first<T>(c, false);
}

// The first message of a kind, whatever comes before it.
template <class T>
T skip_to(DdsChannel& c) {
  return receive_first<T>(c, true);
}

Declare state_topic(const std::string& topic) {
  Declare d;
  d.topic = topic;
  d.type = "linebridge_msgs::msg::dds_::SawStatus_";
  d.max_size = 128;
  return d;
}

}  // namespace

TEST(ChannelMessage, EveryMessageSurvivesItsEncodingAndTruncationIsRefused) {
  Sample s;
  s.id = 7;
  s.connection = 0x0102030405060708;
  s.identity.guid[0] = 0x01;
  s.identity.guid[15] = 0xFE;
  s.identity.seq_high = -1;
  s.identity.seq_low = 42;
  s.partitions = {"saw1", "saw2"};
  s.payload = {0x00, 0x01, 0x00, 0x00, 0xAA, 0xBB};
  const auto bytes = encode(s);
  auto back = decode(bytes);
  ASSERT_TRUE(back) << back.error().message;
  const auto& got = std::get<Sample>(*back);
  EXPECT_EQ(got.id, 7u);
  EXPECT_EQ(got.connection, s.connection);
  EXPECT_EQ(got.identity, s.identity);
  EXPECT_EQ(got.partitions, s.partitions);
  EXPECT_EQ(got.payload, s.payload);

  for (std::size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_FALSE(decode(std::span(bytes.data(), n))) << "a datagram cut to " << n << " bytes was taken";
  }
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_FALSE(decode(longer));
}

TEST(ChannelMessage, TheHelloNamesItsConnectionAndLanesAndADeclarationItsLane) {
  Hello h;
  h.line = "line7";
  h.incarnation = 99;
  h.pid = 1234;
  h.connection = 3;
  h.lanes = 8;
  auto back = decode(encode(h));
  ASSERT_TRUE(back) << back.error().message;
  const auto& hello = std::get<Hello>(*back);
  EXPECT_EQ(hello.line, "line7");
  EXPECT_EQ(hello.pid, 1234);
  EXPECT_EQ(hello.connection, 3u);
  EXPECT_EQ(hello.lanes, 8u);

  Declare d = state_topic("rt/line7/saw1/setpoint");
  d.writer = false;
  d.lane = 5;
  auto declared = decode(encode(d));
  ASSERT_TRUE(declared) << declared.error().message;
  EXPECT_EQ(std::get<Declare>(*declared).lane, 5u);
  EXPECT_EQ(std::get<Declare>(*declared).topic, "rt/line7/saw1/setpoint");
}

TEST(ChannelMessage, AnotherVersionIsRefusedWithTheReason) {
  auto bytes = encode(Ping{});
  bytes[2] = static_cast<std::uint8_t>(kChannelVersion + 1);
  auto m = decode(bytes);
  ASSERT_FALSE(m);
  EXPECT_NE(m.error().message.find("version"), std::string::npos) << m.error().message;
}

TEST(ChannelSocket, TheSocketFileIsOpenOnlyToTheServicesUserAndGroup) {
  const auto path = socket_path("mode");
  auto channel = BusChannel::open({path, "l", 1});
  ASSERT_TRUE(channel) << channel.error().message;
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0660u);
}

TEST(ChannelSocket, AFileThatIsNotASocketIsNeverReplaced) {
  const auto path = socket_path("file");
  { std::ofstream(path) << "mine"; }
  auto channel = BusChannel::open({path, "l", 1});
  ASSERT_FALSE(channel);
  EXPECT_NE(channel.error().message.find("not a socket"), std::string::npos) << channel.error().message;
  EXPECT_TRUE(std::filesystem::exists(path));
  std::filesystem::remove(path);
}

// A DDS side creates one endpoint per declaration, seconds of work at a full line: each state
// endpoint's declaration comes with its newest sample right after it, the ones declared `first`
// (a device's status) before the other states, and every endpoint without a state after them, so
// that a device's status is on DDS as soon as its own writer exists.
TEST(BusChannel, EveryConnectionGetsTheStatesFirstEachWithItsNewestSampleThenTheRestThenReady) {
  const auto path = socket_path("snapshot");
  auto opened = BusChannel::open({path, "line7", 99});
  ASSERT_TRUE(opened) << opened.error().message;
  auto& bus = **opened;
  const auto info = bus.declare(state_topic("rt/line7/saw1/info"), true);
  Declare reader = state_topic("rt/line7/saw1/setpoint");
  const auto setpoint = bus.declare_reader(reader, [](const Sample&) {});
  const auto status = bus.declare(state_topic("rt/line7/saw1/status"), true, true);
  bus.start();
  // Before any DDS side: kept (latest only), nothing sent.
  bus.publish(status, {0, 1, 0, 0, 1});
  bus.publish(status, {0, 1, 0, 0, 2});
  bus.publish(info, {0, 1, 0, 0, 7});

  for (int connection = 1; connection <= 2; ++connection) {
    auto dds = DdsChannel::connect(path, 1000);
    ASSERT_TRUE(dds) << dds.error().message;
    const auto& hello = (*dds)->hello();
    EXPECT_EQ(hello.line, "line7");
    EXPECT_EQ(hello.incarnation, 99u);
    const auto d1 = next<Declare>(**dds);
    EXPECT_EQ(d1.id, status) << "the status, declared last but `first`, comes first";
    EXPECT_TRUE(d1.writer);
    EXPECT_EQ(d1.topic, "rt/line7/saw1/status");
    const auto snap = next<Sample>(**dds);
    EXPECT_EQ(snap.id, status);
    EXPECT_EQ(snap.payload, (std::vector<std::uint8_t>{0, 1, 0, 0, 2})) << "the newest state, not the first";
    const auto d2 = next<Declare>(**dds);
    EXPECT_EQ(d2.id, info) << "the other state endpoint comes before the reader, which has no state";
    EXPECT_EQ(d2.topic, "rt/line7/saw1/info");
    const auto snap2 = next<Sample>(**dds);
    EXPECT_EQ(snap2.id, info);
    EXPECT_EQ(snap2.payload, (std::vector<std::uint8_t>{0, 1, 0, 0, 7}));
    const auto d3 = next<Declare>(**dds);
    EXPECT_EQ(d3.id, setpoint);
    EXPECT_FALSE(d3.writer);
    EXPECT_EQ(next<Ready>(**dds).endpoints, 3u);
    // A sample now goes straight through.
    bus.publish(status, {0, 1, 0, 0, 3});
    EXPECT_EQ(next<Sample>(**dds).payload, (std::vector<std::uint8_t>{0, 1, 0, 0, 3}));
    bus.publish(status, {0, 1, 0, 0, 2});  // the next connection's snapshot
  }
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (bus.counters().connects < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(bus.counters().connects, 2u);
}

TEST(BusChannel, SamplesFromTheDdsSideReachTheirReaderWithTheirIdentity) {
  const auto path = socket_path("reader");
  auto opened = BusChannel::open({path, "l", 1});
  ASSERT_TRUE(opened);
  auto& bus = **opened;
  std::mutex m;
  std::condition_variable cv;
  std::vector<Sample> got;
  const auto id = bus.declare_reader(state_topic("rq/l/bridge/nmtRequest"), [&](const Sample& s) {
    std::lock_guard lock(m);
    got.push_back(s);
    cv.notify_all();
  });
  bus.start();
  auto dds = DdsChannel::connect(path, 1000);
  ASSERT_TRUE(dds);
  skip_to<Ready>(**dds);
  Sample s;
  s.id = id;
  s.identity.guid[3] = 9;
  s.identity.seq_low = 5;
  s.partitions = {"saw1"};
  s.payload = {0, 1, 0, 0, 7};
  ASSERT_TRUE((*dds)->send(s));
  Sample unknown = s;
  unknown.id = 1000;  // no such endpoint: dropped, not a crash
  ASSERT_TRUE((*dds)->send(unknown));
  std::unique_lock lock(m);
  ASSERT_TRUE(cv.wait_for(lock, 20s, [&] { return !got.empty(); }));
  EXPECT_EQ(got[0].identity, s.identity);
  EXPECT_EQ(got[0].partitions, s.partitions);
  EXPECT_EQ(got[0].payload, s.payload);
}

TEST(BusChannel, ADdsSideThatStopsReadingNeverHoldsUpThePublisher) {
  const auto path = socket_path("stalled");
  auto opened = BusChannel::open({path, "l", 1, 64});
  ASSERT_TRUE(opened);
  auto& bus = **opened;
  Declare event = state_topic("rt/l/saw1/cut");
  const auto cuts = bus.declare(event, false);
  const auto status = bus.declare(state_topic("rt/l/saw1/status"), true);
  bus.start();
  auto dds = DdsChannel::connect(path, 1000);  // connected, and never reads again
  ASSERT_TRUE(dds);
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (!bus.counters().connected && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(bus.counters().connected);
  // Far more than the socket's buffer and the queue hold: a publish that waited would hang here.
  const std::vector<std::uint8_t> payload(1000, 0x55);
  for (int i = 0; i < 20000; ++i) {
    bus.publish(cuts, payload);
    bus.publish(status, payload);
  }
  const auto c = bus.counters();
  EXPECT_GT(c.dropped_queue_full, 0u) << "events beyond the queue are dropped and counted";
  EXPECT_LT(c.samples_sent, 20000u);
}

TEST(BusChannel, WithNoDdsSideEventsAreDroppedAndCounted) {
  const auto path = socket_path("nopeer");
  auto opened = BusChannel::open({path, "l", 1});
  ASSERT_TRUE(opened);
  auto& bus = **opened;
  const auto cuts = bus.declare(state_topic("rt/l/saw1/cut"), false);
  bus.start();
  bus.publish(cuts, {0, 1, 0, 0});
  bus.publish(cuts, {0, 1, 0, 0});
  EXPECT_EQ(bus.counters().dropped_no_peer, 2u);
}

// Issue 41: a state sample larger than the socket's send buffer failed every send, the bus side
// dropped the DDS side, and the next one's snapshot carried the same sample: a restart loop. The
// channel now carries every datagram up to kMaxMessage (the socket's send buffer is made to hold
// one: a Unix socket's default, net.core.wmem_default 212992, takes 212960-byte datagrams only)
// and refuses a larger sample at publish: counted, logged, the connection kept.
TEST(BusChannel, ASampleTheChannelCannotCarryIsRefusedAndTheDdsSideStaysConnected) {
  const auto path = socket_path("oversize");
  auto opened = BusChannel::open({path, "l", 1});
  ASSERT_TRUE(opened) << opened.error().message;
  auto& bus = **opened;
  const auto diagnostics = bus.declare(state_topic("rt/l/bridge/diagnostics"), true);
  const auto cuts = bus.declare(state_topic("rt/l/saw1/cut"), false);
  bus.start();
  auto dds = DdsChannel::connect(path, 1000);
  ASSERT_TRUE(dds) << dds.error().message;
  skip_to<Ready>(**dds);

  // The largest sample the channel carries: its datagram is exactly kMaxMessage bytes.
  Sample probe;
  probe.id = diagnostics;
  const std::size_t header = encode(probe).size();
  const std::vector<std::uint8_t> largest(kMaxMessage - header, 0x11);
  bus.publish(diagnostics, largest);
  const auto got = next<Sample>(**dds);
  EXPECT_EQ(got.id, diagnostics);
  EXPECT_EQ(got.payload, largest);

  // One byte more: refused and counted; the DDS side stays connected and gets what follows.
  bus.publish(diagnostics, std::vector<std::uint8_t>(largest.size() + 1, 0x22));
  bus.publish(cuts, {0, 1, 0, 0, 9});
  const auto after = next<Sample>(**dds);
  EXPECT_EQ(after.id, cuts) << "the refused sample was sent, or something came before the next one";
  auto c = bus.counters();
  EXPECT_EQ(c.samples_too_large, 1u);
  EXPECT_EQ(c.connects, 1u);
  EXPECT_TRUE(c.connected);

  // A new DDS side: its snapshot carries the newest sample that fitted, not the refused one.
  dds->reset();
  auto second = DdsChannel::connect(path, 1000);
  ASSERT_TRUE(second) << second.error().message;
  EXPECT_EQ(next<Declare>(**second).id, diagnostics);
  EXPECT_EQ(next<Sample>(**second).payload, largest);
  EXPECT_EQ(next<Declare>(**second).id, cuts);
  EXPECT_EQ(next<Ready>(**second).endpoints, 2u);
  c = bus.counters();
  EXPECT_EQ(c.connects, 2u) << "the first DDS side was dropped and came back";
  EXPECT_TRUE(c.connected);
}

namespace {

// What a bus loop does with its lane: waits (20 s at most) until something is there, then reads.
bool read_lane_when_ready(BusChannel& bus, std::uint32_t lane) {
  pollfd p{bus.lane_fd(lane), POLLIN, 0};
  if (::poll(&p, 1, 20'000) != 1) return false;
  bus.read_lane(lane);
  return true;
}

struct Taken {
  std::mutex m;
  std::condition_variable cv;
  std::vector<std::pair<Sample, std::thread::id>> samples;
  BusChannel::SampleHandler handler() {
    return [this](const Sample& s) {
      std::lock_guard lock(m);
      samples.emplace_back(s, std::this_thread::get_id());
      cv.notify_all();
    };
  }
  std::size_t size() {
    std::lock_guard lock(m);
    return samples.size();
  }
};

// A bus side with one lane and one reader on it, started: what both lane tests begin with.
struct OneLane {
  explicit OneLane(const std::string& name) : opened(BusChannel::open({socket_path(name), "l", 1})) {
    if (!opened) throw std::runtime_error(opened.error().message);
    lane = bus().add_lane();
    Declare setpoint = state_topic("rt/l/saw1/setpoint");
    setpoint.lane = lane;
    reader = bus().declare_reader(setpoint, taken.handler());
  }
  BusChannel& bus() { return **opened; }
  std::string path() const { return (*opened)->path(); }
  lb::Result<std::unique_ptr<BusChannel>> opened;
  Taken taken;
  std::uint32_t lane = 0;
  std::uint32_t reader = 0;
};

}  // namespace

// A set value's reader on a lane: its samples come on the lane's own socket and run on the thread
// that reads the lane (a bus loop), not on the channel's.
TEST(BusChannel, ALaneCarriesItsReadersSamplesToTheThreadThatReadsIt) {
  OneLane line("lane");
  auto& bus = line.bus();
  const auto path = line.path();
  const auto lane = line.lane;
  EXPECT_EQ(lane, 1u);
  auto& on_lane = line.taken;
  Taken off_lane;
  const auto lane_reader = line.reader;
  const auto plain_reader = bus.declare_reader(state_topic("rq/l/bridge/nmtRequest"), off_lane.handler());
  bus.start();
  auto dds = DdsChannel::connect(path, 1000);
  ASSERT_TRUE(dds) << dds.error().message;
  EXPECT_EQ((*dds)->hello().lanes, 1u);
  EXPECT_EQ((*dds)->hello().connection, 1u);
  EXPECT_EQ(skip_to<Declare>(**dds).lane, lane) << "the declaration tells the DDS side the reader's lane";

  Sample s;
  s.id = lane_reader;
  s.identity.seq_low = 11;
  s.payload = {0, 1, 0, 0, 42};
  ASSERT_TRUE((*dds)->send(lane, s));
  ASSERT_TRUE(read_lane_when_ready(bus, lane)) << "nothing came on the lane";
  ASSERT_EQ(on_lane.size(), 1u);
  EXPECT_EQ(on_lane.samples[0].first.payload, s.payload);
  EXPECT_EQ(on_lane.samples[0].first.identity, s.identity);
  EXPECT_EQ(on_lane.samples[0].second, std::this_thread::get_id()) << "the handler ran on the lane's reader";
  EXPECT_EQ(bus.counters().samples_on_lanes, 1u);

  // Another reader's sample on this lane would run on the wrong loop: dropped and counted.
  Sample stray = s;
  stray.id = plain_reader;
  const auto bad_before = bus.counters().bad_messages;
  ASSERT_TRUE((*dds)->send(lane, stray));
  ASSERT_TRUE(read_lane_when_ready(bus, lane));
  EXPECT_EQ(bus.counters().bad_messages, bad_before + 1);
  EXPECT_EQ(off_lane.size(), 0u);

  // A lane the DDS side was not given: its samples go on the channel, to the channel's thread.
  Sample plain = s;
  plain.id = plain_reader;
  ASSERT_TRUE((*dds)->send(7, plain));
  std::unique_lock lock(off_lane.m);
  ASSERT_TRUE(off_lane.cv.wait_for(lock, 20s, [&] { return !off_lane.samples.empty(); }));
  EXPECT_NE(off_lane.samples[0].second, std::this_thread::get_id());
  const auto c = bus.counters();
  EXPECT_EQ(c.samples_on_lanes, 1u) << "only the lane reader's own sample counts as taken on a lane";
  EXPECT_EQ(c.samples_received, 3u) << "the stray counts as received, then as a bad message";
}

// Issue 41: a DDS side that went kept its lane's descriptor, and what it sent there stamped with
// the next (predictable) connection number was taken while the next DDS side was connected. Every
// connection now gets lanes of its own, closed when it ends: the old descriptor is a dead socket.
TEST(BusChannel, ALaneOfAConnectionThatEndedIsDead) {
  OneLane line("lane_stale");
  auto& bus = line.bus();
  const auto lane = line.lane;
  auto& taken = line.taken;
  bus.start();
  // The first DDS side as an attacker holds it: the raw descriptors that came with the Hello.
  auto first = connect_channel(line.path(), 1000);
  ASSERT_TRUE(first) << first.error().message;
  DatagramBuffer buffer;
  auto got = receive_with_fds(first->get(), buffer.room(), 4);
  ASSERT_TRUE(got) << got.error().message;
  ASSERT_EQ(got->fds.size(), 1u);
  auto hello = decode(buffer.first(got->size));
  ASSERT_TRUE(hello && std::holds_alternative<Hello>(*hello));
  const auto first_connection = std::get<Hello>(*hello).connection;
  const UniqueFd kept_lane = std::move(got->fds[0]);
  first->reset();  // the channel ends; the lane's descriptor stays here
  const auto gone_deadline = std::chrono::steady_clock::now() + 20s;
  while (bus.counters().connected && std::chrono::steady_clock::now() < gone_deadline)
    std::this_thread::sleep_for(10ms);
  ASSERT_FALSE(bus.counters().connected);

  auto second = DdsChannel::connect(line.path(), 1000);
  ASSERT_TRUE(second) << second.error().message;
  ASSERT_EQ((*second)->hello().connection, first_connection + 1);
  Sample late;
  late.id = line.reader;
  late.connection = (*second)->hello().connection;  // what the next DDS side stamps: predictable
  late.payload = {0, 1, 0, 0, 1};
  const auto datagram = encode(Message(late));
  errno = 0;
  EXPECT_LT(::send(kept_lane.get(), datagram.data(), datagram.size(), MSG_NOSIGNAL | MSG_DONTWAIT), 0)
      << "the ended connection's lane still takes datagrams";
  EXPECT_TRUE(errno == EPIPE || errno == ECONNRESET || errno == ECONNREFUSED || errno == ENOTCONN)
      << std::strerror(errno);
  pollfd p{bus.lane_fd(lane), POLLIN, 0};
  EXPECT_EQ(::poll(&p, 1, 200), 0) << "the bus loop would be woken by the dead lane";

  Sample fresh = late;
  fresh.payload = {0, 1, 0, 0, 2};
  ASSERT_TRUE((*second)->send(lane, fresh));
  ASSERT_TRUE(read_lane_when_ready(bus, lane));
  ASSERT_EQ(taken.size(), 1u);
  EXPECT_EQ(taken.samples[0].first.payload, fresh.payload);
  const auto c = bus.counters();
  EXPECT_EQ(c.samples_on_lanes, 1u);
  EXPECT_EQ(c.stale_lane_samples, 0u);
}

// A DDS side that closes its lane alone (and keeps the channel) costs it that lane: the bus loop
// is not woken again and again by the lane's end.
TEST(BusChannel, ALaneItsDdsSideClosedNoLongerWakesTheLoop) {
  OneLane line("lane_closed");
  auto& bus = line.bus();
  bus.start();
  auto fd = connect_channel(line.path(), 1000);
  ASSERT_TRUE(fd) << fd.error().message;
  DatagramBuffer buffer;
  auto got = receive_with_fds(fd->get(), buffer.room(), 4);
  ASSERT_TRUE(got) << got.error().message;
  ASSERT_EQ(got->fds.size(), 1u);
  got->fds.clear();  // the lane's only other end
  ASSERT_TRUE(read_lane_when_ready(bus, line.lane)) << "the end of the lane is not seen";
  pollfd p{bus.lane_fd(line.lane), POLLIN, 0};
  EXPECT_EQ(::poll(&p, 1, 200), 0) << "the lane's end wakes its loop again";
  EXPECT_TRUE(bus.counters().connected) << "the channel itself stays";
}

namespace {

// Connects to `path` as another process (a child: fork, then system calls only) of `uid`:`gid`
// with no supplementary group: 0 a Hello came (accepted), 3 the bus side closed the connection
// (refused), 4 the kernel refused the connect (the file's mode), 10 the child could not become
// that user (not root), 1 anything else.
int connect_as(const std::string& path, uid_t uid, gid_t gid) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), std::min(path.size(), sizeof(addr.sun_path) - 1));
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::setgroups(0, nullptr) != 0 || ::setresgid(gid, gid, gid) != 0 || ::setresuid(uid, uid, uid) != 0) _exit(10);
    const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) _exit(errno == EACCES ? 4 : 1);
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 10'000) != 1) _exit(1);
    char buf[1024];
    const auto n = ::recv(fd, buf, sizeof(buf), 0);
    _exit(n > 0 ? 0 : n == 0 ? 3 : 1);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Other users exist for a test only where it runs as the real root (not in a user namespace).
bool can_be_another_user() { return ::geteuid() == 0 && connect_as("/nonexistent", 61099, 61099) != 10; }

}  // namespace

// Issue 41: any process whose user or group was the service's was accepted, and replaced the live
// DDS side. Only the DDS side's user is: a process of another user whose primary group is the
// service's (it can open the socket file) is refused, and so is root.
TEST(BusChannel, OnlyTheDdsSidesUserIsTakenNotItsGroupNorRoot) {
  if (!can_be_another_user()) GTEST_SKIP() << "needs root outside a user namespace (another uid)";
  const auto path = socket_path("peer_uid");
  constexpr uid_t kDds = 61002;
  BusChannel::Options options{path, "l", 1};
  options.peer.uid = kDds;
  auto opened = BusChannel::open(options);
  ASSERT_TRUE(opened) << opened.error().message;
  auto& bus = **opened;
  bus.start();
  // The socket file is this process's (root), mode 0660: its group's members reach it.
  EXPECT_EQ(connect_as(path, 61003, ::getegid()), 3) << "a member of the service's group was accepted";
  EXPECT_EQ(connect_as(path, 61004, 61004), 4) << "the file's mode let another user connect";
  auto as_root = DdsChannel::connect(path, 1000);
  EXPECT_FALSE(as_root) << "root was accepted";
  auto c = bus.counters();
  EXPECT_EQ(c.peers_refused, 2u);
  EXPECT_EQ(c.connects, 0u);
  // The DDS side's user, in the service's group (the units: SupplementaryGroups=linebridge).
  const pid_t pid = ::fork();
  if (pid == 0) {
    const gid_t groups[] = {::getegid()};
    if (::setgroups(1, groups) != 0 || ::setresgid(kDds, kDds, kDds) != 0 || ::setresuid(kDds, kDds, kDds) != 0)
      _exit(10);
    const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::memcpy(addr.sun_path, path.c_str(), std::min(path.size(), sizeof(addr.sun_path) - 1));
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) _exit(4);
    pollfd p{fd, POLLIN, 0};
    char buf[1024];
    _exit(::poll(&p, 1, 10'000) == 1 && ::recv(fd, buf, sizeof(buf), 0) > 0 ? 0 : 3);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the DDS side's user was refused";
  c = bus.counters();
  EXPECT_EQ(c.connects, 1u);
  EXPECT_EQ(c.peers_refused, 2u);
}

// Under linebridge --part both the DDS side is the bus process's own child: another process of the
// same user (this test, connecting itself) is refused; a child of this process is taken.
TEST(BusChannel, UnderPartBothOnlyTheOwnChildIsTaken) {
  const auto path = socket_path("peer_child");
  BusChannel::Options options{path, "l", 1};
  options.peer.own_child_only = true;
  auto opened = BusChannel::open(options);
  ASSERT_TRUE(opened) << opened.error().message;
  auto& bus = **opened;
  bus.start();
  auto not_a_child = DdsChannel::connect(path, 1000);
  EXPECT_FALSE(not_a_child) << "a process that is not this process's child was taken";
  EXPECT_EQ(bus.counters().peers_refused, 1u);
  EXPECT_EQ(connect_as(path, ::geteuid(), ::getegid()), 0) << "this process's child was refused";
  EXPECT_EQ(bus.counters().connects, 1u);
}

// Issue 41: a second connection replaced the live DDS side (20 connections in 4 s ended 8 DDS
// processes). One at a time now: the second is refused, the first keeps being served.
TEST(BusChannel, ASecondDdsSideWhileOneIsConnectedIsRefused) {
  const auto path = socket_path("second");
  auto opened = BusChannel::open({path, "l", 1});
  ASSERT_TRUE(opened) << opened.error().message;
  auto& bus = **opened;
  const auto cuts = bus.declare(state_topic("rt/l/saw1/cut"), false);
  bus.start();
  auto first = DdsChannel::connect(path, 1000);
  ASSERT_TRUE(first) << first.error().message;
  skip_to<Ready>(**first);
  for (int i = 0; i < 3; ++i) {
    auto second = DdsChannel::connect(path, 1000);
    EXPECT_FALSE(second) << "a second DDS side was taken";
  }
  const auto c = bus.counters();
  EXPECT_EQ(c.second_peers_refused, 3u);
  EXPECT_EQ(c.connects, 1u);
  EXPECT_TRUE(c.connected);
  bus.publish(cuts, {0, 1, 0, 0, 5});
  EXPECT_EQ(next<Sample>(**first).payload, (std::vector<std::uint8_t>{0, 1, 0, 0, 5}))
      << "the first DDS side is no longer served";
}

// With no DDS side for the alarm time the channel says so (its counters, which the line's
// diagnostics publish, and the log); a DDS side that connects ends the alarm.
TEST(BusChannel, NoDdsSideForTheAlarmTimeRaisesTheAlarmAndOneThatConnectsEndsIt) {
  const auto path = socket_path("absent");
  BusChannel::Options options{path, "l", 1};
  options.absent_alarm = 300ms;
  auto opened = BusChannel::open(options);
  ASSERT_TRUE(opened) << opened.error().message;
  auto& bus = **opened;
  bus.start();
  const auto wait_alarm = [&](bool on) {
    const auto deadline = std::chrono::steady_clock::now() + 20s;
    while (bus.counters().absent_alarm != on && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(10ms);
    return bus.counters().absent_alarm == on;
  };
  ASSERT_TRUE(wait_alarm(true)) << "no alarm without a DDS side since the start";
  auto c = bus.counters();
  EXPECT_GE(c.absent, 300ms);
  EXPECT_EQ(c.absent_alarms, 1u);
  EXPECT_EQ(bus.last_end(), "");
  {
    auto dds = DdsChannel::connect(path, 1000);
    ASSERT_TRUE(dds) << dds.error().message;
    ASSERT_TRUE(wait_alarm(false));
    c = bus.counters();
    EXPECT_EQ(c.absent, 0ms);
    EXPECT_EQ(c.absent_alarms, 1u);
  }
  ASSERT_TRUE(wait_alarm(true)) << "no alarm after the DDS side went";
  EXPECT_EQ(bus.counters().absent_alarms, 2u);
  // The connection's end as the channel saw it (this process was the DDS side).
  EXPECT_EQ(bus.last_end().rfind("DDS side pid " + std::to_string(::getpid()) + ": ", 0), 0u) << bus.last_end();
  bus.report_end(12345, "exited with 2");
  EXPECT_NE(bus.last_end().find("pid 12345 exited with 2"), std::string::npos) << bus.last_end();
}
