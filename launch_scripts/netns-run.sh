#!/usr/bin/env bash
# Runs a command in a private network namespace with a private /dev/shm, loopback up and multicast
# routed to it: DDS discovery and data stay inside, nothing reaches a real network, and Fast DDS's
# shared-memory transport cannot meet participants of other runs.
#   launch_scripts/netns-run.sh COMMAND [ARGS...]
# Works as root, and as an unprivileged user where user namespaces are allowed (unshare -r).
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: $0 COMMAND [ARGS...]" >&2; exit 2; }

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
