#!/usr/bin/env bash
# The demo line: the saw simulator and the bridge on a virtual CAN bus, DDS kept inside a private
# network namespace (localhost only). Shows the live saw status and cuts, then sends a new product
# length and shows the saw cutting at it. Ctrl-C stops everything cleanly.
#   launch_scripts/demo.sh [--duration SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."

duration=0
while [ $# -gt 0 ]; do
  case "$1" in
    --duration) duration="$2"; shift 2 ;;
    --inside) inside=1; shift ;;
    -h|--help) sed -n '2,6p' "$0"; exit 0 ;;
    *) echo "demo.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done

if [ -z "${inside:-}" ]; then
  ./launch_scripts/setup.sh >&2
  build=${LINEBRIDGE_BUILD_DIR:-build}
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$build" --target linebridge linebridge-sim linebridge-cli
  export LINEBRIDGE_BIN="$PWD/$build/bridge/app"
  exec ./launch_scripts/netns-run.sh "$0" --inside --duration "$duration"
fi

# --- inside the private namespace ---
bin=${LINEBRIDGE_BIN:?}
logdir=$(mktemp -d /tmp/linebridge-demo.XXXXXX)
pids=()
cleanup() {
  trap - EXIT INT TERM
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  echo "demo: stopped (simulator log: $logdir/sim.log)"
}
trap cleanup EXIT
trap 'exit 0' INT TERM
say() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

say "starting the simulators and the bridge (built-in demo line: puller, saw, corrugator on bus 'extrusion' with SYNC 20 ms; a feeder box on bus 'weaving')"
"$bin/linebridge-sim" >"$logdir/sim.log" 2>&1 & pids+=($!)
"$bin/linebridge" 2>&1 & pids+=($!)

say "saw program on, sync speed 100 % (30 m/min), product length 1.0 m"
"$bin/linebridge-cli" set saw1 --program on --sync-speed-percent 100 --product-length-m 1.0 --timeout 10

say "the bridge's diagnostics: every device online and started"
"$bin/linebridge-cli" echo bridge diagnostics --duration 1.5

say "live saw status (1 line/s, and every status change) and cut events"
"$bin/linebridge-cli" echo saw1 status --rate 1 & pids+=($!)
"$bin/linebridge-cli" echo saw1 cut & pids+=($!)
sleep 7

say "new product length 0.4 m: the saw takes it after its next cut"
"$bin/linebridge-cli" set saw1 --product-length-m 0.4

say "a set value out of range is refused and never reaches CAN"
"$bin/linebridge-cli" set saw1 --sync-speed-percent 120 || true

if [ "$duration" != 0 ]; then
  remaining=$(awk -v d="$duration" 'BEGIN { r = d - 9; print (r > 1 ? r : 1) }')
  sleep "$remaining"
else
  say "running until Ctrl-C"
  while true; do sleep 1; done
fi
