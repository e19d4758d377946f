// The key events' journal entries (base/journal_event, app/journal_sink): each kind's MESSAGE_ID
// fixed, well-formed and its own; the fields in the line and back out of it; spdlog's queue (the
// AsyncLog's) carrying an event to the sink, which sends it as an entry of its own under systemd and
// writes every other line as before; a real RemoteNode on a virtual bus logging online and lost with
// its line, bus, device and node; every kind documented in docs/operations.md with its id.
// The journal itself (sd_journal_sendv to journald) is checked in the systemd VM
// (launch_scripts/systemd-vm/check.sh: journalctl MESSAGE_ID=... LB_DEVICE=...).
#include <gtest/gtest.h>
#include <spdlog/async.h>
#include <spdlog/async_logger.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "app/journal_sink.hpp"
#include "base/journal_event.hpp"
#include "can/bus.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/remote_node.hpp"
#include "support/eventually.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
namespace journal = lb::journal;
using journal::Event;

namespace {

// The ids as released (docs/operations.md): a search or an alert that names one must keep finding
// its event, so a change here is a change of the product's interface.
const std::map<Event, std::string> kReleasedIds{
    {Event::device_online, "fecb2be038e74664b679c1f1ed7526f6"},
    {Event::device_lost, "6279545544e24482b4b2b0a619f497d2"},
    {Event::boot_failed, "81ae36bb585b4005a82d8f9b62a26efa"},
    {Event::emcy, "51e2dad1f02c4e3dbc684cece2f56c0d"},
    {Event::bus_off, "a60a2eecec2145e5b8616efcc9551933"},
    {Event::bus_back, "a1a3a975e07e4752b1bec8cd4c4fa09b"},
    {Event::dds_side_gone, "3da26d56a43344538469b32eaa7a10fb"},
    {Event::dds_side_back, "ed00515540b8490389079f63dd96153f"},
    {Event::takeover, "789f545cc4b94fb1a15e75e8d00f15fe"},
    {Event::set_values_refused, "4f3e3f3062044106ad0f5072e28bc48b"},
};

// Every line a logger gave it, as its text.
class CaptureSink final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  std::vector<std::string> lines() {
    std::lock_guard lock(mutex_);
    return lines_;
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    lines_.emplace_back(msg.payload.data(), msg.payload.size());
  }
  void flush_() override {}

 private:
  std::vector<std::string> lines_;
};

// What the sink sent to "the journal": one entry per event, its fields by name.
class CaptureJournal {
 public:
  lb::app::JournalSink::Send send() {
    return [this](const std::vector<std::string>& fields) {
      std::lock_guard lock(mutex_);
      std::map<std::string, std::string> entry;
      for (const auto& f : fields) {
        const auto eq = f.find('=');
        entry[f.substr(0, eq)] = f.substr(eq + 1);
      }
      entries_.push_back(std::move(entry));
      return result_;
    };
  }
  std::vector<std::map<std::string, std::string>> entries() {
    std::lock_guard lock(mutex_);
    return entries_;
  }
  void fail_with(int result) { result_ = result; }

 private:
  std::mutex mutex_;
  std::vector<std::map<std::string, std::string>> entries_;
  int result_ = 0;
};

// spdlog's default logger for the test's life, as the bridge's is (journal::log writes to it).
class DefaultLogger {
 public:
  explicit DefaultLogger(std::shared_ptr<spdlog::logger> logger) : before_(spdlog::default_logger()) {
    logger->set_level(spdlog::level::trace);
    spdlog::set_default_logger(std::move(logger));
  }
  ~DefaultLogger() { spdlog::set_default_logger(before_); }
  DefaultLogger(const DefaultLogger&) = delete;
  DefaultLogger& operator=(const DefaultLogger&) = delete;

 private:
  std::shared_ptr<spdlog::logger> before_;
};

bool lower_hex(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

TEST(JournalEvent, EveryKindHasItsReleasedIdWellFormedAndItsOwn) {
  ASSERT_EQ(journal::kEvents.size(), kReleasedIds.size());
  std::set<std::string> ids;
  std::set<std::string> names;
  for (const auto& [event, id] : kReleasedIds) {
    const auto& k = journal::kind(event);
    EXPECT_EQ(k.event, event);
    EXPECT_EQ(k.message_id, id) << k.name;
    // 128 bits as 32 lower-case hex digits (journalctl matches MESSAGE_ID as text); made by
    // systemd-id128 new: a random (version 4, variant 10xx) id, not a hand-typed pattern.
    EXPECT_EQ(id.size(), 32u) << k.name;
    EXPECT_TRUE(lower_hex(id)) << k.name;
    EXPECT_EQ(id[12], '4') << k.name;
    EXPECT_NE(std::string("89ab").find(id[16]), std::string::npos) << k.name;
    ids.insert(id);
    names.emplace(k.name);
    EXPECT_EQ(journal::kind_named(k.name), &k);
  }
  EXPECT_EQ(ids.size(), kReleasedIds.size()) << "two kinds share an id";
  EXPECT_EQ(names.size(), kReleasedIds.size()) << "two kinds share a name";
}

TEST(JournalEvent, TheLineIsTheMessageThenItsFieldsAndTheyComeBackOut) {
  const auto where = journal::Where::of_device("line1", "extrusion", "saw1", 3);
  const auto line = journal::encode(Event::emcy, where, "socketcan:can0: node 3 EMCY 8130h (monitoring), register 11h",
                                    {{journal::kEmcyCode, "8130"}, {journal::kEmcyRegister, "11"}});
  EXPECT_EQ(line.text, "socketcan:can0: node 3 EMCY 8130h (monitoring), register 11h {LB_EVENT=emcy LB_LINE=line1 "
                       "LB_BUS=extrusion LB_DEVICE=saw1 LB_NODE=3 LB_EMCY_CODE=8130 LB_EMCY_REGISTER=11}");
  EXPECT_EQ(line.trailer, std::string("socketcan:can0: node 3 EMCY 8130h (monitoring), register 11h").size());
  const auto d = journal::decode(line.text, line.trailer);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->kind->event, Event::emcy);
  const std::vector<std::pair<std::string, std::string>> want{
      {"LB_EVENT", "emcy"}, {"LB_LINE", "line1"},     {"LB_BUS", "extrusion"},    {"LB_DEVICE", "saw1"},
      {"LB_NODE", "3"},     {"LB_EMCY_CODE", "8130"}, {"LB_EMCY_REGISTER", "11"},
  };
  EXPECT_EQ(d->fields, want);
}

TEST(JournalEvent, NamesNotGivenAndEmptyFieldsAreLeftOut) {
  const auto line = journal::encode(Event::dds_side_gone, journal::Where::of_line("l"), "gone",
                                    {{journal::kDdsPid, ""}});
  EXPECT_EQ(line.text, "gone {LB_EVENT=dds_side_gone LB_LINE=l}");
}

TEST(JournalEvent, AValueWithSpacesQuotesBracesOrControlCharactersIsQuotedAndComesBackAsItWas) {
  const std::string odd = "saw \"1\" {a\\b}\nnext\x7f";
  const auto line = journal::encode(Event::boot_failed, journal::Where::of_device("", "", odd), "boot failed",
                                    {{journal::kBootError, "J"}});
  EXPECT_EQ(line.text.find('\n'), std::string::npos) << "one line: " << line.text;
  EXPECT_EQ(line.text,
            R"(boot failed {LB_EVENT=boot_failed LB_DEVICE="saw \"1\" {a\\b}\x0Anext\x7F" LB_BOOT_ERROR=J})");
  const auto d = journal::decode(line.text, line.trailer);
  ASSERT_TRUE(d);
  ASSERT_EQ(d->fields.size(), 3u);
  EXPECT_EQ(d->fields[1], (std::pair<std::string, std::string>{"LB_DEVICE", odd}));
  EXPECT_EQ(d->fields[2], (std::pair<std::string, std::string>{"LB_BOOT_ERROR", "J"}));
}

TEST(JournalEvent, ATrailerNotWrittenByEncodeIsNoEvent) {
  const std::string text = "x {LB_EVENT=device_lost LB_NODE=5}";
  EXPECT_TRUE(journal::decode(text, 1));
  EXPECT_FALSE(journal::decode(text, 0));                                        // not where it begins
  EXPECT_FALSE(journal::decode(text, text.size() + 1));                          // beyond the text
  EXPECT_FALSE(journal::decode("x {LB_EVENT=no_such_kind}", 1));                 // an unknown kind
  EXPECT_FALSE(journal::decode("x {LB_NODE=5 LB_EVENT=device_lost}", 1));        // LB_EVENT not first
  EXPECT_FALSE(journal::decode("x {LB_EVENT=device_lost lb_node=5}", 1));        // not a journal field name
  EXPECT_FALSE(journal::decode("x {LB_EVENT=device_lost LB_DEVICE=\"saw}", 1));  // a quote left open
  EXPECT_FALSE(journal::decode("x {LB_EVENT=device_lost  LB_NODE=5}", 1));       // an empty field
}

// As the AsyncLog has it: an asynchronous logger (a queue and its thread) over the sink.
TEST(JournalSink, AnEventCrossesTheLogsQueueAndBecomesAJournalEntryOtherLinesStayLines) {
  CaptureJournal journal_entries;
  auto out = std::make_shared<CaptureSink>();
  auto sink = std::make_shared<lb::app::JournalSink>(out, journal_entries.send(), "linebridge");
  ASSERT_TRUE(sink->to_journal());
  sink->set_pattern("[bridge] %l %v");  // as the bridge's, but for its time of day
  auto pool = std::make_shared<spdlog::details::thread_pool>(64, 1);
  {
    const DefaultLogger logger(
        std::make_shared<spdlog::async_logger>("journal-test", sink, pool, spdlog::async_overflow_policy::block));
    journal::log(Event::device_lost, spdlog::level::warn, journal::Where::of_device("line1", "extrusion", "saw1", 3),
                 "socketcan:can0: node 3 lost: no heartbeat for 500 ms", {{journal::kHeartbeatTimeoutMs, "500"}});
    // A line that looks like an event but was not logged as one.
    spdlog::info("{}", "a plain line {LB_EVENT=device_lost LB_NODE=3}");
    ASSERT_TRUE(lb::test::eventually(10s, [&] { return journal_entries.entries().size() + out->lines().size() >= 2; }));
  }
  const auto entries = journal_entries.entries();
  ASSERT_EQ(entries.size(), 1u);
  const std::map<std::string, std::string> want{
      {"MESSAGE",  // what stdout would have had
       "[bridge] warning socketcan:can0: node 3 lost: no heartbeat for 500 ms {LB_EVENT=device_lost LB_LINE=line1 "
       "LB_BUS=extrusion "
       "LB_DEVICE=saw1 LB_NODE=3 LB_HEARTBEAT_TIMEOUT_MS=500}"},
      {"PRIORITY", "4"},  // warning (syslog)
      {"MESSAGE_ID", "6279545544e24482b4b2b0a619f497d2"},
      {"SYSLOG_IDENTIFIER", "linebridge"},
      {"LB_EVENT", "device_lost"},
      {"LB_LINE", "line1"},
      {"LB_BUS", "extrusion"},
      {"LB_DEVICE", "saw1"},
      {"LB_NODE", "3"},
      {"LB_HEARTBEAT_TIMEOUT_MS", "500"},
  };
  EXPECT_EQ(entries[0], want);
  EXPECT_EQ(out->lines(), std::vector<std::string>{"a plain line {LB_EVENT=device_lost LB_NODE=3}"});
}

TEST(JournalSink, NotUnderSystemdAnEventIsItsPlainLine) {
  auto out = std::make_shared<CaptureSink>();
  auto sink = std::make_shared<lb::app::JournalSink>(out, lb::app::JournalSink::Send(), "linebridge");
  EXPECT_FALSE(sink->to_journal());
  const DefaultLogger logger(std::make_shared<spdlog::logger>("journal-test", sink));
  journal::log(Event::takeover, spdlog::level::warn, journal::Where::of_bus("l", "b"), "bus b: took the bus over",
               {{journal::kMasterNode, "1"}});
  EXPECT_EQ(out->lines(), std::vector<std::string>{
                              "bus b: took the bus over {LB_EVENT=takeover LB_LINE=l LB_BUS=b LB_MASTER_NODE=1}"});
}

TEST(JournalSink, AnEventTheJournalRefusesIsWrittenAsAPlainLineAndCounted) {
  CaptureJournal journal_entries;
  journal_entries.fail_with(-EAGAIN);
  auto out = std::make_shared<CaptureSink>();
  auto sink = std::make_shared<lb::app::JournalSink>(out, journal_entries.send(), "linebridge");
  const DefaultLogger logger(std::make_shared<spdlog::logger>("journal-test", sink));
  journal::log(Event::bus_off, spdlog::level::err, journal::Where::of_bus("", "b"), "bus-off");
  EXPECT_EQ(journal_entries.entries().size(), 1u);
  EXPECT_EQ(out->lines(), std::vector<std::string>{"bus-off {LB_EVENT=bus_off LB_BUS=b}"});
  EXPECT_EQ(sink->journal_failures(), 1u);
}

TEST(JournalSink, PriorityFollowsTheLevel) {
  EXPECT_EQ(lb::app::syslog_priority(spdlog::level::debug), 7);
  EXPECT_EQ(lb::app::syslog_priority(spdlog::level::info), 6);
  EXPECT_EQ(lb::app::syslog_priority(spdlog::level::warn), 4);
  EXPECT_EQ(lb::app::syslog_priority(spdlog::level::err), 3);
  EXPECT_EQ(lb::app::syslog_priority(spdlog::level::critical), 2);
}

TEST(JournalSink, JournalStreamMustNameTheDescriptorsDeviceAndInode) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  std::FILE* other = std::tmpfile();
  ASSERT_NE(other, nullptr);
  struct stat st {};
  ASSERT_EQ(::fstat(::fileno(f), &st), 0);
  const auto stream = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  EXPECT_TRUE(lb::app::is_journal_stream(stream.c_str(), ::fileno(f)));
  EXPECT_FALSE(lb::app::is_journal_stream(stream.c_str(), ::fileno(other)));  // inherited, stdout elsewhere
  EXPECT_FALSE(lb::app::is_journal_stream(nullptr, ::fileno(f)));
  EXPECT_FALSE(lb::app::is_journal_stream("", ::fileno(f)));
  EXPECT_FALSE(lb::app::is_journal_stream((stream + "x").c_str(), ::fileno(f)));
  EXPECT_FALSE(lb::app::is_journal_stream(std::to_string(st.st_dev).c_str(), ::fileno(f)));
  std::fclose(other);
  std::fclose(f);
}

// A real node on a virtual bus: its first heartbeat is device_online, its silence device_lost, each
// with the names the line gave it.
class JournalEventOfANode : public lb::test::LoopOnOwnBus {
 protected:
  JournalEventOfANode() : LoopOnOwnBus("je") {}
};

TEST_F(JournalEventOfANode, OnlineAndLostCarryItsLineBusDeviceAndNode) {
  CaptureJournal journal_entries;
  auto sink = std::make_shared<lb::app::JournalSink>(std::make_shared<CaptureSink>(), journal_entries.send(),
                                                     "linebridge");
  const DefaultLogger logger(std::make_shared<spdlog::logger>("journal-test", sink));
  lb::canopen::RemoteNode node(*loop_, 5, 300ms, true);
  node.name_events(journal::Where::of_device("line1", "extrusion", "saw1"));
  loop_->start();
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x705, {0x7F})));  // pre-operational
  const auto has = [&](const std::string& id) {
    const auto e = journal_entries.entries();
    return std::any_of(e.begin(), e.end(), [&](const auto& x) { return x.at("MESSAGE_ID") == id; });
  };
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return has("6279545544e24482b4b2b0a619f497d2"); }));  // lost
  loop_->stop();
  const auto entries = journal_entries.entries();
  ASSERT_EQ(entries.size(), 2u);
  EXPECT_EQ(entries[0].at("MESSAGE_ID"), "fecb2be038e74664b679c1f1ed7526f6");  // online
  EXPECT_EQ(entries[0].at("LB_NMT_STATE"), "pre-operational");
  EXPECT_EQ(entries[0].at("PRIORITY"), "6");
  EXPECT_EQ(entries[1].at("LB_HEARTBEAT_TIMEOUT_MS"), "300");
  EXPECT_EQ(entries[1].at("PRIORITY"), "4");
  EXPECT_NE(entries[1].at("MESSAGE").find("node 5 lost: no heartbeat for 300 ms"), std::string::npos);
  for (const auto& e : entries) {
    EXPECT_EQ(e.at("LB_LINE"), "line1");
    EXPECT_EQ(e.at("LB_BUS"), "extrusion");
    EXPECT_EQ(e.at("LB_DEVICE"), "saw1");
    EXPECT_EQ(e.at("LB_NODE"), "5");
  }
}

// A real loop on a replayed bus (a LogBus reports a recording's error frames as a live bus does): a
// bus-off, the controller restarted (error-active again), then the recording's end (the link down).
TEST(JournalEventOfABus, BusOffAndBackCarryItsLineAndBus) {
  const auto file = ::testing::TempDir() + "/journal_event_" + std::to_string(::getpid()) + ".log";
  // 300 ms apart, replayed at the recorded pace: the loop sees each state (it looks after each burst).
  std::ofstream(file) << "(1700000000.000000) vcan0 705#05\n"
                         "(1700000000.300000) vcan0 20000040#0000000000000000\n"  // CAN_ERR_BUSOFF
                         "(1700000000.600000) vcan0 20000100#0000000000000000\n"  // CAN_ERR_RESTARTED
                         "(1700000000.900000) vcan0 705#05\n";
  CaptureJournal journal_entries;
  auto sink = std::make_shared<lb::app::JournalSink>(std::make_shared<CaptureSink>(), journal_entries.send(),
                                                     "linebridge");
  const DefaultLogger logger(std::make_shared<spdlog::logger>("journal-test", sink));
  auto bus = lb::can::open_bus("log:" + file);
  ASSERT_TRUE(bus) << bus.error().message;
  lb::canopen::BusLoop loop(std::move(*bus));
  loop.name_events(journal::Where::of_bus("line1", "extrusion"));
  loop.start();
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return journal_entries.entries().size() >= 3; }));
  loop.stop();
  std::remove(file.c_str());
  const auto entries = journal_entries.entries();
  ASSERT_EQ(entries.size(), 3u);
  const std::vector<std::vector<std::string>> want{
      // MESSAGE_ID, LB_BUS_STATE, LB_BUS_STATE_BEFORE, PRIORITY
      {"a60a2eecec2145e5b8616efcc9551933", "bus-off", "", "3"},
      {"a1a3a975e07e4752b1bec8cd4c4fa09b", "error-active", "bus-off", "6"},
      {"a60a2eecec2145e5b8616efcc9551933", "down", "error-active", "3"},
  };
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const auto& e = entries[i];
    EXPECT_EQ(e.at("MESSAGE_ID"), want[i][0]) << i;
    EXPECT_EQ(e.at("LB_BUS_STATE"), want[i][1]) << i;
    if (!want[i][2].empty()) {
      EXPECT_EQ(e.at("LB_BUS_STATE_BEFORE"), want[i][2]) << i;
    }
    EXPECT_EQ(e.at("PRIORITY"), want[i][3]) << i;
    EXPECT_EQ(e.at("LB_LINE"), "line1");
    EXPECT_EQ(e.at("LB_BUS"), "extrusion");
    EXPECT_EQ(e.count("LB_DEVICE"), 0u);
  }
}

// docs/operations.md lists every kind: a table row with its name and id, and the journalctl line
// that finds it; and every field an event may carry.
TEST(JournalEvent, EveryKindAndFieldIsDocumentedInOperationsMd) {
  std::ifstream in(std::string(LB_SOURCE_DIR) + "/docs/operations.md");
  ASSERT_TRUE(in) << "docs/operations.md";
  std::stringstream text;
  text << in.rdbuf();
  std::vector<std::string> rows;
  std::string line;
  while (std::getline(text, line)) {
    if (!line.empty() && line.front() == '|') rows.push_back(line);
  }
  for (const auto& k : journal::kEvents) {
    // Its first two columns: the kind's name and its id.
    const auto row = std::find_if(rows.begin(), rows.end(), [&](const std::string& r) {
      return r.rfind("| `" + std::string(k.name) + "` | `" + std::string(k.message_id) + "` |", 0) == 0;
    });
    ASSERT_NE(row, rows.end()) << "no row of docs/operations.md names " << k.name << " with " << k.message_id;
    EXPECT_NE(row->find("journalctl MESSAGE_ID=" + std::string(k.message_id)), std::string::npos)
        << "its row has no journalctl line: " << *row;
  }
  for (const auto field :
       {journal::kEventField, journal::kLine, journal::kBus, journal::kDevice, journal::kNode, journal::kNmtState,
        journal::kHeartbeatTimeoutMs, journal::kBootError, journal::kSdoAbort, journal::kEmcyCode,
        journal::kEmcyRegister, journal::kEmcyManufacturer, journal::kBusState, journal::kBusStateBefore,
        journal::kDdsPid, journal::kMasterNode, journal::kRestoreScope, journal::kEnablingOff, journal::kKeptRefused}) {
    EXPECT_NE(text.str().find("`" + std::string(field) + "`"), std::string::npos) << field << " not in operations.md";
  }
}

}  // namespace
