#!/usr/bin/env bash
# The fault campaign of issue 40 (docs/testing.md, "The fault campaign"): a line of every device
# type (saw 3.1 and 1.0, puller, corrugator, winder on one virtual bus, the feeder box on a second),
# each device a linebridge-sim process of its own, served by the real bridge, runs for --minutes
# while a schedule drawn from --seed injects faults (device power cycles and stalls, kill -9 of the
# bridge's bus process or DDS process, bridge restarts, spoofed heartbeats / boot-ups / SYNCs /
# SDO writes, stalled DDS clients) and an operator per device keeps setting and stopping; the
# safety table's invariants I1-I3 are checked from the bus and the DDS answers all along. It
# prints the seed, the faults by kind, the stops sent and their time to the bus (p50/p99/max), and
# every violation with its frames. The same seed replays the same faults and requests.
#
#   launch_scripts/fault-campaign.sh [--minutes N] [--seed S] [--mean-gap-s G] [--dir DIR]
#                                    [--build-dir DIR] [--nice N]
#
#   --minutes N      how long the line runs (default 30); faults stop 20 s before the end
#   --seed S         the schedule's seed (default: drawn and printed)
#   --mean-gap-s G   mean time between two faults' beginnings (default 5)
#   --dir DIR        the line's files and every process's log (default /tmp/fault-campaign-PID)
#   --build-dir DIR  the build that holds tests/fault_campaign (default build); build it with
#                    cmake --build DIR --target fault_campaign
#   --nice N         run the whole campaign at this niceness (default 0)
#
# Exit status: 0 no violation; 1 violations (or a bridge process that ended by itself); 2 the
# campaign could not run its course (the line never came up, the recorder lost frames, or Ctrl-C /
# SIGTERM ended it early: faults under way are undone and the verdict is on what ran). Not in CI's
# time budget; CI runs a 2.5-minute seeded run (ctest -R FaultCampaign).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/.." && pwd)

build="$repo/build"
nice_level=0
args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --minutes | --seed | --mean-gap-s | --dir)
      [ $# -ge 2 ] || { echo "$1 needs a value" >&2; exit 2; }
      args+=("$1" "$2")
      shift 2
      ;;
    --build-dir)
      [ $# -ge 2 ] || { echo "$1 needs a value" >&2; exit 2; }
      build=$2
      shift 2
      ;;
    --nice)
      [ $# -ge 2 ] || { echo "$1 needs a value" >&2; exit 2; }
      nice_level=$2
      shift 2
      ;;
    -h | --help)
      sed -n '2,26p' "$0" | sed 's/^# \{0,1\}//'
      exit 0
      ;;
    *)
      echo "unknown argument: $1 (see --help)" >&2
      exit 2
      ;;
  esac
done

program="$build/tests/fault_campaign"
if [ ! -x "$program" ]; then
  echo "no $program: build it first (cmake --build $build --target fault_campaign)" >&2
  exit 2
fi
# Every DDS participant (the bridge's, the campaign's, the clients') runs in a private network
# namespace: nothing leaves the machine or meets another run.
exec nice -n "$nice_level" "$here/netns-run.sh" "$program" "${args[@]}"
