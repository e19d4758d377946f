#pragma once
// linebridge-cli topics: the DDS topics and types of a running line, as discovery reports them
// (with discovery servers the tool asks to learn every endpoint: SUPER_CLIENT), with how many
// writers and readers each has and their QoS, and the participants that hold them.

#include "dds/participant.hpp"
#include "profiles/line_config.hpp"

namespace lb::app {

struct TopicsOptions {
  double wait_s = 3;  // how long discovery runs before the list is printed
  bool all = false;   // every topic of the domain, not only the line's
};

// Returns the exit code: 0 when the line has topics, 1 when none was found (no bridge running?).
int list_topics(const profiles::LineConfig& line, ddsl::ParticipantOptions options, const TopicsOptions& o);

}  // namespace lb::app
