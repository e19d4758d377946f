// The start-up policy's pieces without a bus: which scope a start gets, which levels the profiles
// mark enabling and how they are cleared from a payload, the range checks a kept payload passes,
// and the store's file (format, identity and age, links and FIFOs refused, failures reported).
// Expected payloads and names come from CiA 420-4 / 420-2 / 414-2 as the profiles encode them
// (saw RPDO1: 6020h, 6005h, 6002h; puller RPDO1: 6020h, 6002h; feeder RPDO2: 600Ah, 6004h).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "canopen/pdo_mapping.hpp"
#include "gateways/persistence/set_value_restore.hpp"
#include "gateways/persistence/set_value_store.hpp"
#include "profiles/profile_registry.hpp"
#include "support/scratch_files.hpp"

using lb::canopen::PdoEntry;
using lb::gateways::check_set_values;
using lb::gateways::clear_enabling;
using lb::gateways::enabling_levels;
using lb::gateways::force_enabling;
using lb::gateways::restore_scope;
using lb::gateways::RestoreScope;
using lb::gateways::SetValueStore;
using lb::profiles::StartupPolicy;
using namespace std::chrono_literals;

namespace {

const lb::profiles::ProfileRegistry& registry() {
  static const auto r = lb::profiles::ProfileRegistry::builtin();
  return r;
}
const lb::profiles::Profile& profile(const char* id, const char* version) {
  const auto* p = registry().find(id, version);
  if (p == nullptr) throw std::runtime_error(std::string("no profile ") + id);
  return *p;
}
lb::canopen::PdoMapping mapping(std::initializer_list<std::uint32_t> words) {
  std::vector<PdoEntry> m;
  for (auto w : words) m.push_back(PdoEntry::from_u32(w));
  return lb::canopen::PdoMapping::create(std::move(m)).value();
}
const auto kSawRpdo1 = mapping({0x60200010, 0x60050010, 0x60020020});
const auto kPullerRpdo1 = mapping({0x60200010, 0x60020010});
const auto kFeederRpdo2 = mapping({0x600A0008, 0x60040020});

std::string temp_dir(const std::string& name) { return lb::test::fresh_dir("svr-" + name); }
std::int64_t unix_now() {
  return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}
const SetValueStore::Key kSaw{"extrusion", 5, "cia420-4@3.1", "rpdo1"};

}  // namespace

TEST(RestoreScope, OnlyADeviceFoundRunningGetsItsEnablingLevelsBack) {
  StartupPolicy policy;  // defaults: non_enabling after a power loss, restart never
  EXPECT_EQ(restore_scope(policy, true, false), RestoreScope::all);
  EXPECT_EQ(restore_scope(policy, false, false), RestoreScope::non_enabling);
  // A device that starts itself at power-on proves nothing by being operational.
  EXPECT_EQ(restore_scope(policy, true, true), RestoreScope::non_enabling);
  policy.after_power_loss = StartupPolicy::AfterPowerLoss::nothing;
  EXPECT_EQ(restore_scope(policy, false, false), RestoreScope::nothing);
  EXPECT_EQ(restore_scope(policy, true, false), RestoreScope::all);
  policy = {};
  policy.restart_after_power_loss = StartupPolicy::Restart::allowed;
  EXPECT_EQ(restore_scope(policy, false, false), RestoreScope::all);
  // Paused by its boot to write PDO parameters: found running, but nothing enabling comes back.
  policy = {};
  EXPECT_EQ(restore_scope(policy, true, false, true), RestoreScope::non_enabling);
}

TEST(Enabling, TheProfilesMarkTheLevelsThatLetAMachineRun) {
  const auto& saw = profile("cia420-4", "3.1");
  std::vector<std::string> marked;
  for (const auto& f : saw.bitset("control_word")->bits) {
    if (f.enabling) marked.push_back(f.name);
  }
  EXPECT_EQ(marked, (std::vector<std::string>{"saw_program_on", "wall_thickening"}));
  for (const auto* key : {"1.0"}) {
    const auto& p = profile("cia420-2", key);
    EXPECT_TRUE(p.bitset("control_word")->field("extruder_running")->enabling);
    EXPECT_FALSE(p.bitset("control_word")->field("motor_stop")->enabling);  // start prevention stays as it was
  }
  EXPECT_TRUE(profile("cia420-3", "3.1").bitset("control_word")->field("extruder_running")->enabling);
  EXPECT_TRUE(profile("cia420-4", "1.0").bitset("control_word")->field("saw_program_on")->enabling);
  EXPECT_TRUE(profile("cia414-2", "1.1").object("loom_status")->enabling);
  EXPECT_TRUE(profile("cia414-2", "1.1").object("digital_outputs_1")->enabling);
}

TEST(Enabling, ClearedFromAPayloadAndNamed) {
  // Saw: 0007h = program on, wall thickening, length change toggled; 50.00 %; 1.2 m.
  std::array<std::uint8_t, 8> saw{0x07, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00};
  const auto cleared = clear_enabling(profile("cia420-4", "3.1"), kSawRpdo1, saw);
  EXPECT_EQ(cleared, (std::vector<std::string>{"saw_program_on", "wall_thickening"}));
  EXPECT_EQ(saw, (std::array<std::uint8_t, 8>{0x04, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00}));
  // Puller: 0041h = extruder running and motor stop (start prevention); -25.00 % (F63Ch).
  std::array<std::uint8_t, 4> puller{0x41, 0x00, 0x3C, 0xF6};
  EXPECT_EQ(clear_enabling(profile("cia420-2", "1.0"), kPullerRpdo1, puller),
            std::vector<std::string>{"extruder_running"});
  EXPECT_EQ(puller, (std::array<std::uint8_t, 4>{0x01, 0x00, 0x3C, 0xF6}));
  // Feeder box RPDO2: loom status 1 (start advice) goes to 0 (stop); 6004h untouched.
  std::array<std::uint8_t, 5> loom{0x01, 0x2C, 0x01, 0x96, 0x00};
  EXPECT_EQ(clear_enabling(profile("cia414-2", "1.1"), kFeederRpdo2, loom), std::vector<std::string>{"loom_status"});
  EXPECT_EQ(loom, (std::array<std::uint8_t, 5>{0x00, 0x2C, 0x01, 0x96, 0x00}));
  // Nothing enabling set: nothing named, nothing changed.
  std::array<std::uint8_t, 8> off{0x04, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00};
  EXPECT_TRUE(clear_enabling(profile("cia420-4", "3.1"), kSawRpdo1, off).empty());
  EXPECT_EQ(off[0], 0x04);
}

// What tells a stop from a switch-on (DeviceOutput tries a change on forced copies): every
// enabling level with its value, and all of them forced on (all ones) or off, other bits kept.
TEST(Enabling, ReadAndForcedInAPayload) {
  const auto& saw = profile("cia420-4", "3.1");
  // 0005h: program on, the length-change toggle (bit 2), wall thickening off.
  const std::array<std::uint8_t, 8> on{0x05, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00};
  const auto levels = enabling_levels(saw, kSawRpdo1, on);
  ASSERT_EQ(levels.size(), 2u);
  EXPECT_EQ(levels[0].name, "saw_program_on");
  EXPECT_EQ(levels[0].value, 1u);
  EXPECT_EQ(levels[1].name, "wall_thickening");
  EXPECT_EQ(levels[1].value, 0u);
  auto forced = on;
  force_enabling(saw, kSawRpdo1, forced, true);
  EXPECT_EQ(forced, (std::array<std::uint8_t, 8>{0x07, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00}));
  force_enabling(saw, kSawRpdo1, forced, false);
  EXPECT_EQ(forced, (std::array<std::uint8_t, 8>{0x04, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00}));
  // Feeder RPDO2: loom status (600Ah) is one UNSIGNED8 level: forced on, all ones (FFh).
  std::array<std::uint8_t, 5> loom{0x00, 0x2C, 0x01, 0x96, 0x00};
  force_enabling(profile("cia414-2", "1.1"), kFeederRpdo2, loom, true);
  EXPECT_EQ(loom, (std::array<std::uint8_t, 5>{0xFF, 0x2C, 0x01, 0x96, 0x00}));
  const auto loom_levels = enabling_levels(profile("cia414-2", "1.1"), kFeederRpdo2, loom);
  ASSERT_EQ(loom_levels.size(), 1u);
  EXPECT_EQ(loom_levels[0].name, "loom_status");
  EXPECT_EQ(loom_levels[0].value, 0xFFu);
  // A payload shorter than the mapping is left alone and names nothing.
  std::array<std::uint8_t, 2> short_payload{0x05, 0x00};
  force_enabling(saw, kSawRpdo1, short_payload, false);
  EXPECT_EQ(short_payload[0], 0x05);
  EXPECT_TRUE(enabling_levels(saw, kSawRpdo1, short_payload).empty());
}

TEST(KeptSetValues, PassTheRangeChecksOfANewSetValue) {
  const auto& saw = profile("cia420-4", "3.1");
  const std::array<std::uint8_t, 8> ok{0x05, 0x00, 0x10, 0x27, 0xE0, 0x2E, 0x00, 0x00};  // 100.00 %: the maximum
  EXPECT_TRUE(check_set_values(saw, kSawRpdo1, ok));
  const std::array<std::uint8_t, 8> fast{0x05, 0x00, 0xFF, 0xFF, 0xE0, 0x2E, 0x00, 0x00};  // 655.35 %
  const auto r = check_set_values(saw, kSawRpdo1, fast);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("saw_sync_speed_set_value"), std::string::npos) << r.error().message;
  // Puller speed is signed: -100.00 % (D8F0h) passes, -100.01 % (D8EFh) does not.
  EXPECT_TRUE(
      check_set_values(profile("cia420-2", "1.0"), kPullerRpdo1, std::array<std::uint8_t, 4>{0, 0, 0xF0, 0xD8}));
  EXPECT_FALSE(
      check_set_values(profile("cia420-2", "1.0"), kPullerRpdo1, std::array<std::uint8_t, 4>{0, 0, 0xEF, 0xD8}));
  // A loom status the profile does not define (9).
  EXPECT_FALSE(check_set_values(profile("cia414-2", "1.1"), kFeederRpdo2, std::array<std::uint8_t, 5>{9, 0, 0, 0, 0}));
}

TEST(Enabling, TheProfileFormatChecksTheMarks) {
  const std::string head = "profile: t\nversion: \"1\"\ndevice: t\ndevice_type: 0x01A4\nobjects:\n"
                           "  - {index: 0x6020, name: control_word, type: UNSIGNED16, access: rw}\n"
                           "  - {index: 0x6030, name: status_word, type: UNSIGNED16, access: ro}\n";
  auto p = lb::profiles::parse_profile(
      head + "bitsets:\n  control_word:\n    object: 0x6020\n    enabling: [run]\n    bits: {run: 0, stop: 1}\n",
      "t.yaml");
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_TRUE(p->bitset("control_word")->field("run")->enabling);
  EXPECT_FALSE(p->bitset("control_word")->field("stop")->enabling);
  p = lb::profiles::parse_profile(
      head + "bitsets:\n  control_word:\n    object: 0x6020\n    enabling: [runn]\n    bits: {run: 0}\n", "t.yaml");
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find("no field 'runn'"), std::string::npos) << p.error().message;
  p = lb::profiles::parse_profile(
      head + "bitsets:\n  status_word:\n    object: 0x6030\n    enabling: [ready]\n    bits: {ready: 0}\n", "t.yaml");
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find("not written by the master"), std::string::npos) << p.error().message;
}

TEST(SetValueStoreFile, KeepsWhatTheDeviceIsAndWhenItWasInForce) {
  const auto dir = temp_dir("roundtrip");
  {
    auto store = SetValueStore::open(dir, "line", true);
    ASSERT_TRUE(store) << store.error().message;
    EXPECT_FALSE((*store)->restored(kSaw));
    (*store)->save(kSaw, {{0x4C420000, 0x04200004, 0x00010000, 0x12345678},
                          0,
                          {0x60200010, 0x60050010, 0x60020020},
                          {0x05, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00}});
  }  // written at the stop at the latest
  const auto text = lb::test::read_text(dir + "/line.set_values");
  EXPECT_NE(text.find("format 2\n"), std::string::npos) << text;
  EXPECT_NE(text.find("extrusion 5 cia420-4@3.1 4C420000:04200004:00010000:12345678 "), std::string::npos) << text;
  EXPECT_NE(text.find(" rpdo1 60200010,60050010,60020020 05008813E02E0000\n"), std::string::npos) << text;
  auto again = SetValueStore::open(dir, "line", true);
  ASSERT_TRUE(again) << again.error().message;
  const auto kept = (*again)->restored(kSaw);
  ASSERT_TRUE(kept);
  EXPECT_EQ(kept->identity, (std::array<std::uint32_t, 4>{0x4C420000, 0x04200004, 0x00010000, 0x12345678}));
  EXPECT_LE(std::abs(unix_now() - kept->held_at_s), 5);
  EXPECT_EQ(kept->payload, (std::vector<std::uint8_t>{0x05, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00}));
  // Another node-ID, bus or profile is another device: nothing kept for it.
  EXPECT_FALSE((*again)->restored({"extrusion", 6, "cia420-4@3.1", "rpdo1"}));
  EXPECT_FALSE((*again)->restored({"extrusion", 5, "cia420-4@1.0", "rpdo1"}));
  EXPECT_FALSE((*again)->restored({"weaving", 5, "cia420-4@3.1", "rpdo1"}));
}

TEST(SetValueStoreFile, AnOlderFormatOrJunkRestoresNothing) {
  const auto dir = temp_dir("format1");
  // Format 1 was keyed by device name alone: renaming devices moved a saw's program to another.
  std::ofstream(dir + "/line.set_values")
      << "# linebridge: the set values in force\nsaw1 rpdo1 60200010,60050010,60020020 0100881300000000\n";
  {
    auto store = SetValueStore::open(dir, "line", true);
    ASSERT_TRUE(store) << store.error().message;
    EXPECT_FALSE((*store)->restored({"", 0, "", "rpdo1"}));
  }
  // 1 MiB of junk lines after the format line: refused quickly, nothing restored.
  std::string junk = "format 2\n";
  while (junk.size() < (1u << 20) - 2) junk += "x\n";
  std::ofstream(dir + "/line.set_values", std::ios::trunc) << junk;
  auto junky = SetValueStore::open(dir, "line", true);
  ASSERT_TRUE(junky) << junky.error().message;
  EXPECT_FALSE((*junky)->restored(kSaw));
}

TEST(SetValueStoreFile, LinksFifosAndNonDirectoriesAreRefusedNotFollowed) {
  const auto dir = temp_dir("links");
  const auto target = dir + "/elsewhere";
  std::ofstream(target) << "precious\n";
  ASSERT_EQ(::symlink(target.c_str(), (dir + "/line.set_values").c_str()), 0);
  auto linked = SetValueStore::open(dir, "line", true);
  ASSERT_FALSE(linked);
  EXPECT_NE(linked.error().message.find("link"), std::string::npos) << linked.error().message;
  std::filesystem::remove(dir + "/line.set_values");

  ASSERT_EQ(::mkfifo((dir + "/line.set_values").c_str(), 0600), 0);
  auto fifo = SetValueStore::open(dir, "line", true);  // must not hang on the FIFO
  ASSERT_FALSE(fifo);
  EXPECT_NE(fifo.error().message.find("not a regular file"), std::string::npos) << fifo.error().message;
  std::filesystem::remove(dir + "/line.set_values");

  auto file_as_dir = SetValueStore::open(target, "line", true);
  ASSERT_FALSE(file_as_dir);
  EXPECT_NE(file_as_dir.error().message.find("not a directory"), std::string::npos) << file_as_dir.error().message;

  // A link planted at the temporary name is replaced, its target never written.
  ASSERT_EQ(::symlink(target.c_str(), (dir + "/line.set_values.tmp").c_str()), 0);
  {
    auto store = SetValueStore::open(dir, "line", true);
    ASSERT_TRUE(store) << store.error().message;
    (*store)->save(kSaw, {{}, 0, {0x60200010}, {0x01, 0x00}});
  }
  EXPECT_EQ(lb::test::read_text(target), "precious\n");
  EXPECT_NE(lb::test::read_text(dir + "/line.set_values").find(" rpdo1 60200010 0100\n"), std::string::npos);
  struct stat st {};
  ASSERT_EQ(::lstat((dir + "/line.set_values").c_str(), &st), 0);
  EXPECT_TRUE(S_ISREG(st.st_mode));
}

TEST(SetValueStoreFile, AFailingWriteIsReportedAndCounted) {
  const auto dir = temp_dir("failing");
  auto store = SetValueStore::open(dir, "line", true);
  ASSERT_TRUE(store) << store.error().message;
  EXPECT_EQ((*store)->problem(), "");
  std::filesystem::remove_all(dir);  // the directory goes away under the running bridge
  (*store)->save(kSaw, {{}, 0, {0x60200010}, {0x01, 0x00}});
  const auto end = std::chrono::steady_clock::now() + 20s;
  while ((*store)->write_failures() == 0 && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(20ms);
  EXPECT_GT((*store)->write_failures(), 0u);
  EXPECT_NE((*store)->problem().find("No such file or directory"), std::string::npos) << (*store)->problem();
  // Back: the next try succeeds and the problem is gone.
  std::filesystem::create_directories(dir);
  const auto end2 = std::chrono::steady_clock::now() + 20s;
  while (!(*store)->problem().empty() && std::chrono::steady_clock::now() < end2) std::this_thread::sleep_for(20ms);
  EXPECT_EQ((*store)->problem(), "");
  EXPECT_NE(lb::test::read_text(dir + "/line.set_values").find(" rpdo1 60200010 0100\n"), std::string::npos);
}
