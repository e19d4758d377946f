#!/usr/bin/env bash
# The demo line: the saw simulator and the bridge on a virtual CAN bus, DDS kept inside a private
# network namespace (localhost only). Shows the live saw status and cuts, then sends a new product
# length and shows the saw cutting at it. Ctrl-C stops everything cleanly.
#   launch_scripts/demo.sh [--duration SECONDS] [--secure]
# --secure: the same line with DDS Security: a PKI made on the spot (launch_scripts/pki.sh), the
# bridge with its own identity, the CLI as an operator of saw1 and as an observer, and what an
# observer and an unauthenticated client cannot do.
set -euo pipefail
cd "$(dirname "$0")/.."

duration=0
secure=0
while [ $# -gt 0 ]; do
  case "$1" in
    --duration) duration="$2"; shift 2 ;;
    --secure) secure=1; shift ;;
    --inside) inside=1; shift ;;
    -h|--help) sed -n '2,8p' "$0"; exit 0 ;;
    *) echo "demo.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done

if [ -z "${inside:-}" ]; then
  ./launch_scripts/setup.sh >&2
  build=${LINEBRIDGE_BUILD_DIR:-build}
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$build" --target linebridge linebridge-sim linebridge-cli linebridge-security
  export LINEBRIDGE_BIN="$PWD/$build/bridge/app"
  secure_flag=()
  ((secure)) && secure_flag=(--secure)
  exec ./launch_scripts/netns-run.sh "$0" --inside --duration "$duration" "${secure_flag[@]}"
fi

# --- inside the private namespace ---
bin=${LINEBRIDGE_BIN:?}
logdir=$(mktemp -d /tmp/linebridge-demo.XXXXXX)
pids=()
# Stopped in the reverse order of their start: the watching clients first (a client that saw its
# bridge go would say it waits for it), then the bridge, then the simulator. Each is waited for;
# any that did not end cleanly (exit 0 after SIGTERM) is named.
cleanup() {
  local status=$? failed=() i p code
  trap - EXIT INT TERM
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do
    p=${pids[i]}
    kill -TERM "$p" 2>/dev/null || true
    code=0
    wait "$p" 2>/dev/null || code=$?
    [ "$code" -eq 0 ] || failed+=("${names[i]} (exit $code)")
  done
  if ((${#failed[@]})); then
    echo "demo: stopped; not cleanly: ${failed[*]} (simulator log: $logdir/sim.log)"
  elif [ "$status" -ne 0 ]; then
    echo "demo: stopped after a failed step (exit $status; simulator log: $logdir/sim.log)"
  else
    echo "demo: stopped cleanly (simulator log: $logdir/sim.log)"
  fi
}
trap cleanup EXIT
trap 'exit 0' INT TERM
say() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

# Every process reads the same line file; the CLI calls are as an operator of saw1 (set values) or
# as an observer (everything it only watches). Unsecured, all three are the built-in demo line.
line=()
operator=()
observer=()
if ((secure)); then
  pki="$logdir/pki"
  say "DDS Security: a PKI for the demo line (launch_scripts/pki.sh; keys in $pki, made now, never shipped)"
  # pki.sh init prints the dds.security block for the line file; it goes in after localhost_only.
  ./launch_scripts/pki.sh init --config config/lines/demo.yaml --dir "$pki" | sed -n '/^  security:/,$p' >"$logdir/security.yaml"
  ./launch_scripts/pki.sh issue --config config/lines/demo.yaml --dir "$pki" --name op1 --role operator --devices saw1
  ./launch_scripts/pki.sh issue --config config/lines/demo.yaml --dir "$pki" --name hmi --role observer
  secured="$logdir/demo-secured.yaml"
  sed "/^  localhost_only:/r $logdir/security.yaml" config/lines/demo.yaml >"$secured"
  "$bin/linebridge-security" --config "$secured" check
  line=(--config "$secured")
  operator=(--identity "$pki/op1")
  observer=(--identity "$pki/hmi")
fi

say "starting the simulators and the bridge (demo line: puller, saw, corrugator on bus 'extrusion' with SYNC 20 ms; a feeder box on bus 'weaving')"
"$bin/linebridge-sim" "${line[@]}" >"$logdir/sim.log" 2>&1 & pids+=($!) names+=(linebridge-sim)
"$bin/linebridge" "${line[@]}" 2>&1 & pids+=($!) names+=(linebridge)
echo "demo: to watch from another terminal, join this namespace (PID $$), e.g. the raw frames of bus extrusion:"
echo "      launch_scripts/netns-run.sh --join $$ $bin/linebridge-cli ${line[*]} candump extrusion"

say "saw program on, sync speed 100 % (30 m/min), product length 1.0 m"
"$bin/linebridge-cli" "${line[@]}" "${operator[@]}" set saw1 --program on --sync-speed-percent 100 --product-length-m 1.0 --timeout 10

say "the bridge's diagnostics: every device online and started"
"$bin/linebridge-cli" "${line[@]}" "${observer[@]}" echo bridge diagnostics --duration 1.5

say "live saw status (1 line/s, and every status change) and cut events"
"$bin/linebridge-cli" "${line[@]}" "${observer[@]}" echo saw1 status --rate 1 & pids+=($!) names+=("echo saw1 status")
"$bin/linebridge-cli" "${line[@]}" "${observer[@]}" echo saw1 cut & pids+=($!) names+=("echo saw1 cut")
sleep 7

say "new product length 0.4 m: the saw takes it after its next cut"
"$bin/linebridge-cli" "${line[@]}" "${operator[@]}" set saw1 --product-length-m 0.4

say "a set value out of range is refused and never reaches CAN"
"$bin/linebridge-cli" "${line[@]}" "${operator[@]}" set saw1 --sync-speed-percent 120 || true

if ((secure)); then
  say "an observer may watch but not set: its permissions grant no set-value writer"
  "$bin/linebridge-cli" "${line[@]}" "${observer[@]}" set saw1 --product-length-m 0.5 --timeout 3 || true
  say "the operator of saw1 may not command the puller (its request would travel in partition 'puller1', not granted)"
  "$bin/linebridge-cli" "${line[@]}" "${operator[@]}" press puller1 motor_start --timeout 3 || true
  say "an unauthenticated client on the same domain sees nothing for 3 s (the built-in, unsecured demo line)"
  "$bin/linebridge-cli" echo saw1 status --duration 3 || true
  echo "(nothing received)"
fi

if [ "$duration" != 0 ]; then
  remaining=$(awk -v d="$duration" -v s="$secure" 'BEGIN { r = d - (s ? 17 : 9); print (r > 1 ? r : 1) }')
  sleep "$remaining"
else
  say "running until Ctrl-C"
  while true; do sleep 1; done
fi
