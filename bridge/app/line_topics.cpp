#include "app/line_topics.hpp"

#include <fmt/format.h>

#include <chrono>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "app/arguments.hpp"

namespace lb::app {
namespace {

struct Topic {
  std::string type;
  std::string qos;
  std::set<std::string> writers, readers;  // endpoint GUIDs
  std::set<std::string> participants;      // GUID prefixes
};

// What discovery reported so far; discovery callbacks run on Fast DDS threads.
class Discovered {
 public:
  void add(const ddsl::DiscoveryEvent& e) {
    std::lock_guard lock(mutex_);
    if (e.kind == ddsl::DiscoveryEvent::Kind::participant) {
      if (e.removed)
        participants_.erase(e.guid);
      else
        participants_[e.guid] = e.name;
      return;
    }
    auto& t = topics_[e.name];
    auto& set = e.kind == ddsl::DiscoveryEvent::Kind::writer ? t.writers : t.readers;
    if (e.removed) {
      set.erase(e.guid);
      return;
    }
    set.insert(e.guid);
    t.type = e.type;
    if (e.kind == ddsl::DiscoveryEvent::Kind::writer || t.qos.empty())
      t.qos = e.qos;  // a writer's QoS is what it offers
    t.participants.insert(e.guid.substr(0, e.guid.find('|')));
  }
  std::map<std::string, Topic> topics() const {
    std::lock_guard lock(mutex_);
    return topics_;
  }
  std::string participant(const std::string& prefix) const {
    std::lock_guard lock(mutex_);
    auto it = participants_.find(prefix);
    return it == participants_.end() ? prefix : it->second;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::string, Topic> topics_;
  std::map<std::string, std::string> participants_;
};

bool of_line(const std::string& topic, const std::string& line) {
  const std::string part = "/" + line + "/";
  return topic.size() > 3 && topic.compare(2, part.size(), part) == 0;  // rt/<line>/..., rq/<line>/..., rr/<line>/...
}

}  // namespace

int list_topics(const profiles::LineConfig& line, ddsl::ParticipantOptions options, const TopicsOptions& o) {
  Discovered discovered;
  options.see_all_endpoints = true;
  options.on_discovery = [&discovered](const ddsl::DiscoveryEvent& e) { discovered.add(e); };
  auto dds = ddsl::Participant::create_checked(options);
  if (!dds)
    return fmt::print(stderr, "{}\n", dds.error().message), dds.error().configuration ? kExitUsage : kExitFailure;
  std::this_thread::sleep_for(duration_ms(o.wait_s));
  const auto topics = discovered.topics();
  std::size_t shown = 0;
  for (const auto& [name, t] : topics) {
    if (!o.all && !of_line(name, line.line)) continue;
    if (t.writers.empty() && t.readers.empty()) continue;
    std::string who;
    for (const auto& p : t.participants) {
      const auto n = discovered.participant(p);
      if (who.find(n) == std::string::npos) who += (who.empty() ? "" : ", ") + n;
    }
    fmt::print("{:<44} {:<52} writers {} readers {} [{}] ({})\n", name, t.type, t.writers.size(), t.readers.size(),
               t.qos, who);
    ++shown;
  }
  if (shown == 0) {
    fmt::print(stderr, "no topic of {} discovered within {} s on DDS domain {} (is its bridge running?)\n",
               o.all ? "any line" : "line " + line.line, o.wait_s, line.dds.domain);
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace lb::app
