#!/usr/bin/env bash
# Runs a command in a private network namespace with a private /dev/shm, loopback up and multicast
# routed to it: DDS discovery and data stay inside, nothing reaches a real network, and Fast DDS's
# shared-memory transport cannot meet participants of other runs.
#   launch_scripts/netns-run.sh COMMAND [ARGS...]
# Works as root, and as an unprivileged user where user namespaces are allowed (unshare -r).
#
#   launch_scripts/netns-run.sh --join PID|NAME COMMAND [ARGS...]
# Runs COMMAND in the namespaces of a process already running in one (its network namespace: its
# virtual CAN buses and DDS; its mount namespace: its private /dev/shm), e.g. a second terminal
# watching the running demo's bus:
#   launch_scripts/netns-run.sh --join PID build/bridge/app/linebridge-cli candump extrusion
# (demo.sh prints the command with its PID). NAME: the newest process of that exact name.
set -euo pipefail
usage() { echo "usage: $0 [--join PID|NAME] COMMAND [ARGS...]" >&2; exit 2; }
[ $# -ge 1 ] || usage

if [ "$1" = --join ]; then
  [ $# -ge 3 ] || usage
  target=$2
  shift 2
  if [[ $target =~ ^[0-9]+$ ]]; then
    pid=$target
  else
    pid=$(pgrep -n -x -- "$target") || { echo "netns-run: no process named $target" >&2; exit 2; }
  fi
  [ -e "/proc/$pid/ns/net" ] || { echo "netns-run: no process $pid" >&2; exit 2; }
  ns=(--net --mount)
  # Unprivileged, the namespaces belong to the user namespace unshare -r made: enter it first.
  if [ "$(readlink "/proc/$pid/ns/user")" != "$(readlink /proc/self/ns/user)" ]; then
    ns=(--user --preserve-credentials "${ns[@]}")
  fi
  # The working directory stays this one (nsenter would move to the target's): relative paths work.
  exec nsenter --target "$pid" "${ns[@]}" --wd="$PWD" -- env LINEBRIDGE_NETNS=1 "$@"
fi

if [ "${LINEBRIDGE_NETNS:-}" = "1" ]; then
  exec "$@"  # already inside one: nesting would separate this command from its siblings
fi

as_user=()
[ "$(id -u)" -eq 0 ] || as_user=(-r)

exec unshare "${as_user[@]}" -n -m --propagation private -- bash -c '
  set -e
  mount -t tmpfs -o size=512m tmpfs /dev/shm
  ip link set lo up
  ip link set lo multicast on
  ip route add 224.0.0.0/4 dev lo src 127.0.0.1
  export LINEBRIDGE_NETNS=1
  exec "$@"
' netns-run "$@"
