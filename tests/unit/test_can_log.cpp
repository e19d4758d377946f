// Record and replay on the host: can-utils' log format (lines exactly as candump -l writes them),
// the controller state an error frame implies, the log: replay bus (pace, filter, refusal, bad
// lines, end of file), the recording decorator, and the configuration keys for both. The same code
// against the real candump and a real vcan runs in tests/socketcan (inside the VM).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/can/error.h>
#include <poll.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <fstream>
#include <future>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "can/candump_log.hpp"
#include "can/controller_state.hpp"
#include "can/log_bus.hpp"
#include "can/recording_bus.hpp"
#include "can/unique_fd.hpp"
#include "can/virtual_bus.hpp"
#include "profiles/line_config.hpp"
#include "support/drain_bus.hpp"
#include "support/scratch_files.hpp"

namespace lb::can {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

CanFrame parse_one(std::string_view line) {
  auto r = parse_log_line(line);
  if (!r) throw std::runtime_error(r.error().message);
  if (!*r) throw std::runtime_error("blank");
  return (*r)->frame;
}

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "/can_log_" + std::to_string(::getpid()) + "_" + name;
}

std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = temp_path(name);
  std::ofstream(path) << text;
  return path;
}

using lb::test::drain;

// --- the format ---------------------------------------------------------------------------------

TEST(CandumpLog, ParsesAStandardFrameAsCandumpWritesIt) {
  auto r = parse_log_line("(1700000000.123456) vcan0 183#0200785634120000\n");
  ASSERT_TRUE(r) << r.error().message;
  ASSERT_TRUE(*r);
  EXPECT_EQ((*r)->interface, "vcan0");
  const CanFrame& f = (*r)->frame;
  EXPECT_EQ(f.id, 0x183u);
  EXPECT_FALSE(f.extended);
  EXPECT_FALSE(f.rtr);
  EXPECT_FALSE(f.error);
  ASSERT_EQ(f.len, 8);
  EXPECT_EQ(f.data, (std::array<std::uint8_t, 8>{0x02, 0x00, 0x78, 0x56, 0x34, 0x12, 0x00, 0x00}));
  EXPECT_EQ(f.timestamp_ns, 1'700'000'000'123'456'000);
}

TEST(CandumpLog, ParsesExtendedRemoteErrorAndEmptyFrames) {
  const CanFrame eff = parse_one("(1700000000.000001) can0 12345678#DEAD");
  EXPECT_TRUE(eff.extended);
  EXPECT_EQ(eff.id, 0x12345678u);
  EXPECT_EQ(eff.len, 2);
  EXPECT_EQ(eff.data[0], 0xDE);

  const CanFrame low_eff = parse_one("(1700000000.000001) can0 00000080#");  // 29-bit id 0x80
  EXPECT_TRUE(low_eff.extended);
  EXPECT_EQ(low_eff.id, 0x80u);
  EXPECT_EQ(low_eff.len, 0);

  const CanFrame rtr = parse_one("(1700000000.000002) can0 705#R");
  EXPECT_TRUE(rtr.rtr);
  EXPECT_EQ(rtr.id, 0x705u);
  EXPECT_EQ(rtr.len, 0);
  const CanFrame rtr4 = parse_one("(1700000000.000002) can0 1FFFFFFF#R4");
  EXPECT_TRUE(rtr4.rtr);
  EXPECT_TRUE(rtr4.extended);
  EXPECT_EQ(rtr4.len, 4);

  // Bus-off with error counters, as the kernel reports it: CAN_ERR_FLAG | CAN_ERR_BUSOFF | CNT.
  const CanFrame err = parse_one("(1700000000.000003) can0 20000240#0000000000000000");
  EXPECT_TRUE(err.error);
  EXPECT_EQ(err.id, static_cast<std::uint32_t>(CAN_ERR_BUSOFF | CAN_ERR_CNT));
  EXPECT_EQ(err.len, 8);

  const CanFrame sync = parse_one("(1700000000.000004) can0 080#");
  EXPECT_EQ(sync.id, 0x80u);
  EXPECT_EQ(sync.len, 0);
}

TEST(CandumpLog, AcceptsPaddedNamesExtraFieldsSeparatorsAndRawDlc) {
  // candump -l any pads shorter interface names; candump -x appends the direction.
  const CanFrame padded = parse_one("(1700000000.100000)  can0 123#11  R");
  EXPECT_EQ(padded.id, 0x123u);
  EXPECT_EQ(padded.len, 1);
  const CanFrame dotted = parse_one("(1700000000.100000) can0 123#11.22.33");
  EXPECT_EQ(dotted.len, 3);
  EXPECT_EQ(dotted.data[2], 0x33);
  const CanFrame dlc = parse_one("(1700000000.100000) can0 123#1122334455667788_E");
  EXPECT_EQ(dlc.len, 8);
  EXPECT_EQ(parse_one("(1700000000.5) can0 123#").timestamp_ns, 1'700'000'000'500'000'000);
  auto blank = parse_log_line("   \n");
  ASSERT_TRUE(blank);
  EXPECT_FALSE(*blank);
}

TEST(CandumpLog, RefusesWhatIsNotAClassicalFrame) {
  for (const char* bad : {"(1700000000.000000) can0 123##311223344",          // CAN FD
                          "(1700000000.000000) can0 1234#11",                 // 4-digit id
                          "(1700000000.000000) can0 800#11",                  // 11 bits overflow
                          "(1700000000.000000) can0 123#112",                 // odd digits
                          "(1700000000.000000) can0 123#112233445566778899",  // 9 bytes
                          "(1700000000.000000) can0 123#R9",                  // RTR length > 8
                          "(1700000000.000000) can0 12G#11",                  // not hex
                          "1700000000.000000 can0 123#11",                    // no parentheses
                          "(1700000000) can0 123#11",                         // no fraction
                          "(1700000000.000000) can0",                         // no frame
                          "(1700000000.000000) can0 12311"}) {                // no '#'
    EXPECT_FALSE(parse_log_line(bad)) << bad;
  }
  auto fd = parse_log_line("(1700000000.000000) can0 123##311223344");
  ASSERT_FALSE(fd);
  EXPECT_NE(fd.error().message.find("CAN FD"), std::string::npos) << fd.error().message;
}

// Found by fuzz_candump_log: 66666666660 s times 10^9 overflowed the nanoseconds (undefined
// behaviour; in practice a wrapped, wrong time). A time past the year 2262 is refused.
TEST(CandumpLog, RefusesATimestampTheNanosecondsCannotHold) {
  EXPECT_FALSE(parse_log_line("(66666666660.0) can0 123#11"));
  EXPECT_FALSE(parse_log_line("(999999999999999999.999999) can0 123#11"));
  EXPECT_EQ(parse_one("(9223372035.000001) can0 123#11").timestamp_ns, 9'223'372'035'000'001'000);
}

TEST(CandumpLog, FormatsExactlyAsCandumpLogs) {
  CanFrame f = make_frame(0x183, {0x02, 0x00, 0x78, 0x56, 0x34, 0x12, 0x00, 0x00});
  f.timestamp_ns = 1'700'000'000'123'456'789;
  EXPECT_EQ(format_log_line(f, "vcan0"), "(1700000000.123456) vcan0 183#0200785634120000\n");

  CanFrame eff = make_frame(0x1ABCDEF, {0xDE, 0xAD});
  eff.extended = true;
  eff.timestamp_ns = 5'000'001'000;  // seconds are zero-padded to 10 digits
  EXPECT_EQ(format_log_line(eff, "can1"), "(0000000005.000001) can1 01ABCDEF#DEAD\n");

  CanFrame rtr;
  rtr.id = 0x705;
  rtr.rtr = true;
  EXPECT_EQ(format_log_line(rtr, "can0"), "(0000000000.000000) can0 705#R\n");
  rtr.len = 1;
  EXPECT_EQ(format_log_line(rtr, "can0"), "(0000000000.000000) can0 705#R1\n");

  CanFrame err = make_frame(CAN_ERR_CRTL, {0x00, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0x80, 0x00});
  err.error = true;
  EXPECT_EQ(format_log_line(err, "can0"), "(0000000000.000000) can0 20000004#0020000000008000\n");

  CanFrame sync;
  sync.id = 0x80;
  EXPECT_EQ(format_log_line(sync, "can0"), "(0000000000.000000) can0 080#\n");
}

TEST(CandumpLog, EveryFrameKindRoundTrips) {
  for (const char* line :
       {"(1700000000.123456) vcan0 183#0200785634120000\n", "(1700000001.000000) vcan0 12345678#DEAD\n",
        "(1700000002.000001) vcan0 701#R\n", "(1700000002.000001) vcan0 701#R8\n",
        "(1700000003.999999) vcan0 20000040#0000000000000000\n", "(1700000004.000000) vcan0 080#\n"}) {
    auto r = parse_log_line(line);
    ASSERT_TRUE(r && *r) << line;
    EXPECT_EQ(format_log_line((*r)->frame, (*r)->interface), line);
  }
}

// --- controller state ---------------------------------------------------------------------------

CanFrame error_frame(std::uint32_t cls, std::uint8_t ctrl = 0, std::uint8_t tec = 0, std::uint8_t rec = 0) {
  CanFrame f = make_frame(cls, {0x00, ctrl, 0, 0, 0, 0, tec, rec});
  f.error = true;
  return f;
}

TEST(ControllerState, FollowsTheErrorFramesUpAndDown) {
  BusStats s;
  s.state = BusState::error_active;
  apply_error_frame(error_frame(CAN_ERR_PROT), s);  // a bit error alone says nothing of the state
  EXPECT_EQ(s.state, BusState::error_active);
  apply_error_frame(error_frame(CAN_ERR_CRTL | CAN_ERR_CNT, CAN_ERR_CRTL_TX_WARNING, 96, 3), s);
  EXPECT_EQ(s.state, BusState::error_warning);
  EXPECT_EQ(s.tx_error_counter, 96);
  EXPECT_EQ(s.rx_error_counter, 3);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_PASSIVE), s);
  EXPECT_EQ(s.state, BusState::error_passive);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_WARNING), s);  // back down
  EXPECT_EQ(s.state, BusState::error_warning);
  apply_error_frame(error_frame(CAN_ERR_BUSOFF), s);
  apply_error_frame(error_frame(CAN_ERR_BUSOFF), s);  // repeated report: one bus-off
  EXPECT_EQ(s.state, BusState::bus_off);
  EXPECT_EQ(s.bus_offs, 1u);
  apply_error_frame(error_frame(CAN_ERR_RESTARTED), s);
  EXPECT_EQ(s.state, BusState::error_active);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_PASSIVE), s);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE), s);
  EXPECT_EQ(s.state, BusState::error_active);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW), s);
  EXPECT_EQ(s.rx_overflows, 1u);
  EXPECT_EQ(s.state, BusState::error_active);
}

// --- replay -------------------------------------------------------------------------------------

constexpr const char* kRecording = "(1700000000.000000) vcan0 705#05\n"
                                   "(1700000000.050000) vcan0 185#0200785634120000\n"
                                   "(1700000000.050100) can1 123#FF\n"
                                   "(1700000000.100000) vcan0 20000040#0000000000000000\n"
                                   "(1700000000.150000) vcan0 12345678#0102\n"
                                   "(1700000000.200000) vcan0 701#R\n";

TEST(LogBus, SpecSyntax) {
  auto plain = LogBus::parse_spec("/tmp/a.log");
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->path, "/tmp/a.log");
  EXPECT_EQ(plain->pace, LogBus::Pace::realtime);
  auto full = LogBus::parse_spec("rec/b.log?pace=fast&interface=can1");
  ASSERT_TRUE(full);
  EXPECT_EQ(full->path, "rec/b.log");
  EXPECT_EQ(full->pace, LogBus::Pace::fast);
  EXPECT_EQ(full->interface, "can1");
  EXPECT_FALSE(LogBus::parse_spec("a.log?pace=slow"));
  EXPECT_FALSE(LogBus::parse_spec("a.log?speed=2"));
  EXPECT_FALSE(LogBus::parse_spec("?pace=fast"));
  auto missing = open_bus("log:/nonexistent/x.log");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("cannot open"), std::string::npos) << missing.error().message;
  EXPECT_FALSE(open_bus("log:" + write_file("notalog", "hello world\n")));
  EXPECT_FALSE(open_bus("log:" + write_file("empty", "\n")));
}

TEST(LogBus, ReplaysEveryFrameAtTheRecordedPace) {
  auto bus = open_bus("log:" + write_file("pace.log", kRecording));
  ASSERT_TRUE(bus) << bus.error().message;
  const auto t0 = Clock::now();
  const auto frames = drain(**bus, 6);
  const auto elapsed = Clock::now() - t0;
  ASSERT_EQ(frames.size(), 6u);
  EXPECT_GE(elapsed, 195ms) << "the last frame was recorded 200 ms after the first";
  EXPECT_LT(elapsed, 1500ms);
  EXPECT_EQ(frames[0].id, 0x705u);
  EXPECT_EQ(frames[1].data[0], 0x02);
  EXPECT_EQ(frames[1].timestamp_ns, 1'700'000'000'050'000'000) << "recorded timestamps are kept";
  EXPECT_EQ(frames[2].id, 0x123u);
  EXPECT_TRUE(frames[3].error);
  EXPECT_TRUE(frames[4].extended);
  EXPECT_TRUE(frames[5].rtr);
  const BusStats s = (*bus)->stats();
  EXPECT_EQ(s.frames_in, 5u);
  EXPECT_EQ(s.error_frames, 1u);
  EXPECT_EQ(s.bus_offs, 1u) << "a replayed bus-off is reported like a live one";
  auto after = (*bus)->receive();
  ASSERT_TRUE(after);
  EXPECT_FALSE(*after);
  EXPECT_EQ((*bus)->stats().state, BusState::down) << "the recording has ended";
}

TEST(LogBus, FastPaceFiltersByInterfaceAndRefusesToSend) {
  std::string big;
  for (int i = 0; i < 1000; ++i) {
    char line[80];
    std::snprintf(line, sizeof line, "(%010d.000000) vcan0 181#%04X\n", 1'700'000'000 + i, i);  // 1 s apart
    big += line;
    if (i % 100 == 0) big += "(1700000000.000000) can1 123#FF\n";
  }
  auto bus = open_bus("log:" + write_file("fast.log", big) + "?pace=fast&interface=vcan0");
  ASSERT_TRUE(bus) << bus.error().message;
  const auto t0 = Clock::now();
  const auto frames = drain(**bus, 1000, 5000ms);
  EXPECT_LT(Clock::now() - t0, 3s) << "1000 s of recording, as fast as it reads";
  ASSERT_EQ(frames.size(), 1000u);
  for (int i = 0; i < 1000; ++i) ASSERT_EQ(frames[static_cast<std::size_t>(i)].data[1], i & 0xFF) << i;

  auto sent = (*bus)->send(make_frame(0x201, {1}));
  ASSERT_FALSE(sent);
  EXPECT_NE(sent.error().message.find("monitor"), std::string::npos) << sent.error().message;
  EXPECT_EQ((*bus)->stats().tx_dropped, 1u);
}

TEST(LogBus, FastPaceYieldsToTheCallersLoop) {
  std::string big;
  for (int i = 0; i < 500; ++i) big += "(1700000000.000000) vcan0 181#00\n";
  auto bus = LogBus::open(write_file("batch.log", big) + "?pace=fast");
  ASSERT_TRUE(bus);
  int in_a_row = 0;
  for (;;) {
    auto r = (*bus)->receive();
    ASSERT_TRUE(r);
    if (!*r) break;
    ++in_a_row;
  }
  EXPECT_GT(in_a_row, 0);
  EXPECT_LT(in_a_row, 500) << "a bus loop draining until nothing is due must get control back between batches";
  pollfd p{(*bus)->fd(), POLLIN, 0};
  EXPECT_EQ(::poll(&p, 1, 100), 1) << "and be woken again for the rest";
}

// log:/dev/zero never finished starting and grew ~450 MB/s (one endless "line"); a FIFO without a
// writer blocked the open. Only a regular file replays, and a line is never held whole.
TEST(LogBus, OnlyARegularFileReplaysAndAnEndlessLineIsNotHeldWhole) {
  auto bus = open_bus("log:/dev/zero");
  ASSERT_FALSE(bus);
  EXPECT_NE(bus.error().message.find("/dev/zero is not a regular file"), std::string::npos) << bus.error().message;
  const auto fifo = temp_path("fifo.log");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  bus = open_bus("log:" + fifo);
  ::unlink(fifo.c_str());
  ASSERT_FALSE(bus);
  EXPECT_NE(bus.error().message.find("is not a regular file"), std::string::npos) << bus.error().message;

  // 64 MB without a line break, then a frame: the frame replays, the long line is refused.
  const auto path = temp_path("long_line.log");
  {
    std::ofstream out(path);
    out << "(1700000000.000000) vcan0 181#01\n";
    const std::string chunk(1 << 20, 'x');
    for (int i = 0; i < 64; ++i) out << chunk;
    out << "\n(1700000000.000000) vcan0 181#02\n";
  }
  bus = open_bus("log:" + path + "?pace=fast");
  ASSERT_TRUE(bus) << bus.error().message;
  std::vector<CanFrame> frames;
  for (int i = 0; i < 20 && frames.size() < 2; ++i) {
    auto r = (*bus)->receive();
    if (r && *r) frames.push_back(**r);
  }
  ::unlink(path.c_str());
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].data[0], 0x02);
  long rss_kb = 0;
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmHWM:", 0) == 0) rss_kb = std::stol(line.substr(6));
  }
  EXPECT_LT(rss_kb, 60 * 1024) << "the 64 MB line was held in memory";
}

TEST(LogBus, ABadLineIsReportedWithItsPlaceAndSkipped) {
  const std::string path = write_file("bad.log", "(1700000000.000000) vcan0 181#01\n"
                                                 "(1700000000.000000) vcan0 181##0102\n"
                                                 "(1700000000.000000) vcan0 181#03\n");
  auto bus = open_bus("log:" + path + "?pace=fast");
  ASSERT_TRUE(bus);
  std::vector<CanFrame> frames;
  std::vector<std::string> errors;
  for (int i = 0; i < 20 && frames.size() < 2; ++i) {
    auto r = (*bus)->receive();
    if (!r) {
      errors.push_back(r.error().message);
    } else if (*r) {
      frames.push_back(**r);
    }
  }
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].data[0], 0x03);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find(path + ":2:"), std::string::npos) << errors[0];
}

// --- recording ----------------------------------------------------------------------------------

TEST(RecordingBus, RecordsReceivedAndSentFramesAndTheRecordingReplays) {
  const std::string name = "rec" + std::to_string(::getpid());
  auto peer = VirtualBus::open(name);
  ASSERT_TRUE(peer);
  auto inner = open_bus("virtual:" + name);
  ASSERT_TRUE(inner);
  const std::string path = temp_path("rec.log");
  ::unlink(path.c_str());
  auto rec = RecordingBus::open(std::move(*inner), path);
  ASSERT_TRUE(rec) << rec.error().message;

  CanFrame eff = make_frame(0x1234567, {0xAA});
  eff.extended = true;
  ASSERT_TRUE((*peer)->send(make_frame(0x185, {1, 2, 3})));
  ASSERT_TRUE((*peer)->send(eff));
  ASSERT_EQ(drain(**rec, 2).size(), 2u);
  ASSERT_TRUE((*rec)->send(make_frame(0x205, {9, 8})));
  ASSERT_TRUE((*rec)->send(make_frame(0x080, {})));

  // The recording is written by a thread of its own (never on the bus loop): it reaches the file
  // within moments, not at once.
  std::string text;
  std::vector<std::string> lines;
  for (const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
       lines.size() < 4 && std::chrono::steady_clock::now() < until;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    text = lb::test::read_text(path);
    lines.clear();
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
  }
  ASSERT_EQ(lines.size(), 4u) << text;
  EXPECT_NE(lines[0].find(" " + name + " 185#010203"), std::string::npos) << lines[0];
  EXPECT_NE(lines[1].find(" " + name + " 01234567#AA"), std::string::npos) << lines[1];
  EXPECT_NE(lines[2].find(" " + name + " 205#0908"), std::string::npos) << lines[2];
  EXPECT_NE(lines[3].find(" 080#"), std::string::npos) << lines[3];
  EXPECT_EQ((*rec)->stats().record_errors, 0u);

  auto replay = open_bus("log:" + path + "?pace=fast");
  ASSERT_TRUE(replay) << replay.error().message;
  const auto frames = drain(**replay, 4);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[0].id, 0x185u);
  EXPECT_TRUE(frames[1].extended);
  EXPECT_EQ(frames[2].id, 0x205u);
  EXPECT_EQ(frames[3].id, 0x80u);
}

// A recording nobody reads (a FIFO whose reader is late) fills the pipe and then the ring: each
// frame beyond is counted, none is lost uncounted, and the bus goes on delivering meanwhile. Once the
// reader reads, the ring's lines follow: every frame is either a whole line in the FIFO, in order,
// or one record error.
TEST(RecordingBus, AFullRecordingCountsEveryFrameItCannotKeep) {
  constexpr std::size_t kFrames = 150'000;  // ~6.7 MB of lines: more than the ring and the pipe hold
  const std::string source_line = "(1700000000.000000) vcan0 181#0102030405060708\n";
  const std::string recorded_line = "(1700000000.000000) log 181#0102030405060708\n";
  std::string log;
  log.reserve(kFrames * source_line.size());
  for (std::size_t i = 0; i < kFrames; ++i) log += source_line;
  const auto replayed = write_file("full_source.log", log);
  const auto fifo = temp_path("full.fifo");
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  UniqueFd reader{::open(fifo.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};  // not read until the bus is done
  ASSERT_TRUE(reader);

  auto inner = open_bus("log:" + replayed + "?pace=fast");
  ASSERT_TRUE(inner) << inner.error().message;
  auto rec = RecordingBus::open(std::move(*inner), fifo);
  ASSERT_TRUE(rec) << rec.error().message;
  ASSERT_EQ(drain(**rec, kFrames, 60'000ms).size(), kFrames)
      << "the bus stopped delivering when its recording was full";
  const std::uint64_t errors = (*rec)->stats().record_errors;  // final: no frame comes any more
  EXPECT_GT(errors, 0u);
  EXPECT_LT(errors, kFrames);

  std::string text;
  char buf[1 << 16];
  const auto expected_lines = kFrames - errors;
  // Lines counted as they come: counting the whole text after every read was quadratic, and under
  // ThreadSanitizer beside a CPU burner it kept the reader behind its deadline (88,770 of 94,595
  // lines read in 20 s). The deadline is generous; the wait ends when the last line is in.
  std::size_t lines = 0;
  for (const auto until = Clock::now() + 45s; lines < expected_lines && Clock::now() < until;) {
    const ssize_t n = ::read(reader.get(), buf, sizeof buf);
    if (n > 0) {
      text.append(buf, static_cast<std::size_t>(n));
      lines += static_cast<std::size_t>(std::count(buf, buf + n, '\n'));
    } else {
      pollfd p{reader.get(), POLLIN, 0};
      ::poll(&p, 1, 50);
    }
  }
  rec->reset();  // the writer stops; nothing is left to write
  for (ssize_t n; (n = ::read(reader.get(), buf, sizeof buf)) > 0;) text.append(buf, static_cast<std::size_t>(n));
  ::unlink(replayed.c_str());
  ::unlink(fifo.c_str());
  EXPECT_EQ(static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')), expected_lines)
      << errors << " record errors counted";
  ASSERT_EQ(text.size() % recorded_line.size(), 0u) << "whole lines only";
  for (std::size_t at = 0; at < text.size(); at += recorded_line.size()) {
    ASSERT_EQ(text.compare(at, recorded_line.size(), recorded_line), 0) << "line " << at / recorded_line.size();
  }
}

// The descriptor this process has open on `path` (the recording's own), or -1: the same inode.
int open_descriptor_of(const std::string& path) {
  struct stat want {};
  if (::stat(path.c_str(), &want) != 0) return -1;
  for (int fd = 0; fd < 1024; ++fd) {
    struct stat st {};
    if (::fstat(fd, &st) == 0 && st.st_dev == want.st_dev && st.st_ino == want.st_ino) return fd;
  }
  return -1;
}

// The stop is bounded whatever the file does, even when a write() never returns (a hung network
// file system; here a FIFO nobody reads, written without O_NONBLOCK): the destructor used to wait
// for it forever. Now it returns after kStopWait + kStopGrace and leaves the writer behind, which
// ends on its own (and closes the file) once its write returns.
TEST(RecordingBus, StoppingIsBoundedWhenAWriteNeverReturns) {
  constexpr std::size_t kFrames = 5'000;  // ~225 kB of lines: more than the pipe holds (64 KiB)
  std::string log;
  for (std::size_t i = 0; i < kFrames; ++i) log += "(1700000000.000000) vcan0 181#0102030405060708\n";
  const auto replayed = write_file("stuck_source.log", log);
  const auto fifo = temp_path("stuck.fifo");
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto inner = open_bus("log:" + replayed + "?pace=fast");
  ASSERT_TRUE(inner) << inner.error().message;
  auto rec = RecordingBus::open(std::move(*inner), fifo);
  ASSERT_TRUE(rec) << rec.error().message;
  // Makes the recording's writes block, as a file on a stuck disk does: the same descriptor, its
  // O_NONBLOCK cleared (the recording sets it, and the kernel honours it for a FIFO).
  const int fd = open_descriptor_of(fifo);
  ASSERT_GE(fd, 0) << "the recording's descriptor was not found";
  ASSERT_EQ(::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK), 0);

  ASSERT_EQ(drain(**rec, kFrames, 60'000ms).size(), kFrames);
  const auto stop_began = Clock::now();
  auto stopped = std::async(std::launch::async, [&] { rec->reset(); });
  const bool bounded = stopped.wait_for(RecordingBus::kStopWait + RecordingBus::kStopGrace + 10s) ==
                       std::future_status::ready;
  const auto stop_took = Clock::now() - stop_began;

  // A reader now: it releases the blocked write (and a destructor that waits for it, so the test
  // ends either way), and reads until the end of the file, which comes once the writer, left
  // behind or not, has closed the recording (the FIFO's only writer).
  UniqueFd reader{::open(fifo.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};
  ASSERT_TRUE(reader);
  std::size_t lines = 0;
  bool end_of_file = false;
  char buf[1 << 16];
  for (const auto until = Clock::now() + 30s; !end_of_file && Clock::now() < until;) {
    const ssize_t n = ::read(reader.get(), buf, sizeof buf);
    if (n > 0) lines += static_cast<std::size_t>(std::count(buf, buf + n, '\n'));
    end_of_file = n == 0;
    if (n < 0) {
      pollfd p{reader.get(), POLLIN, 0};
      ::poll(&p, 1, 50);
    }
  }
  stopped.get();
  ::unlink(replayed.c_str());
  ::unlink(fifo.c_str());
  EXPECT_TRUE(bounded) << "the destructor waited for a write() that does not return";
  EXPECT_LT(stop_took, RecordingBus::kStopWait + RecordingBus::kStopGrace + 5s);
  EXPECT_TRUE(end_of_file) << "the writer left behind never ended";
  // Whole lines only, never more than were recorded (the write under way when it was released
  // may finish; what came after the deadline is dropped).
  EXPECT_GT(lines, 0u);
  EXPECT_LE(lines, kFrames);
}

TEST(RecordingBus, AnUnwritableFileFailsAtOpen) {
  auto inner = open_bus("virtual:recfail" + std::to_string(::getpid()));
  ASSERT_TRUE(inner);
  auto rec = RecordingBus::open(std::move(*inner), "/nonexistent-dir/x.log");
  ASSERT_FALSE(rec);
  EXPECT_NE(rec.error().message.find("/nonexistent-dir/x.log"), std::string::npos);
}

// --- configuration --------------------------------------------------------------------------------

std::string line_with_bus(const std::string& bus_yaml) {
  return "line: t\nbuses:\n  - " + bus_yaml +
         "\ndevices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n";
}

TEST(LogBusConfig, ALogBusIsAMonitorAndRecordTakesAPath) {
  const auto registry = profiles::ProfileRegistry::builtin();
  auto replay = profiles::parse_line_config(line_with_bus("{name: b, interface: 'log:/tmp/x.log?pace=fast'}"), "t.yaml",
                                            registry);
  ASSERT_TRUE(replay) << replay.error().message;
  EXPECT_EQ(replay->buses[0].role, profiles::BusRole::monitor) << "a replay never transmits: monitor by default";

  auto master = profiles::parse_line_config(line_with_bus("{name: b, interface: 'log:/tmp/x.log', role: master}"),
                                            "t.yaml", registry);
  ASSERT_FALSE(master);
  EXPECT_NE(master.error().message.find("t.yaml:3:"), std::string::npos) << master.error().message;
  EXPECT_NE(master.error().message.find("monitor"), std::string::npos) << master.error().message;

  auto pace = profiles::parse_line_config(line_with_bus("{name: b, interface: 'log:/tmp/x.log?pace=slow'}"), "t.yaml",
                                          registry);
  ASSERT_FALSE(pace);
  EXPECT_NE(pace.error().message.find("pace"), std::string::npos) << pace.error().message;

  auto rec = profiles::parse_line_config(line_with_bus(
                                             "{name: b, interface: 'socketcan:can0', record: /var/log/can0.log}"),
                                         "t.yaml", registry);
  ASSERT_TRUE(rec) << rec.error().message;
  EXPECT_EQ(rec->buses[0].record, "/var/log/can0.log");
  EXPECT_EQ(rec->buses[0].role, profiles::BusRole::master);
  EXPECT_FALSE(profiles::parse_line_config(line_with_bus("{name: b, interface: 'socketcan:can0', record: ''}"),
                                           "t.yaml", registry));
}

}  // namespace
}  // namespace lb::can
