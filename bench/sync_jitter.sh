#!/usr/bin/env bash
# SYNC interval jitter on a real vcan0 (issue 44, point 5): the bridge's own SYNC (the bus loop's
# timerfd, at normal scheduling and at the packaged realtime_priority 40) against a SYNC the kernel's
# broadcast manager sends (bench/bcm_sync.py: CAN_BCM TX_SETUP, SETTIMER|STARTTIMER, count 0,
# ival2 = the period), each alone and with CPU burners in the guest. bench-sync-jitter (the same
# meter as bench.sh's jitter figure, here on socketcan:vcan0: kernel receive stamps) records every
# SYNC; per case the script prints the intervals, their mean, p50/p99/p99.9/max of
# |interval - period| (us), those off by over 1 ms and those longer than 1.5 periods.
# Then checks what a kernel SYNC does when its process stops: SIGTERM, SIGKILL (both end it), SIGSTOP
# (it goes on: the hazard of a frozen master).
#   bench/sync_jitter.sh [--duration S] [--burners N] [--period-us US] [--out DIR] [--build DIR]
#                        [--cases "loop loop-rt40 kernel"]
# Runs itself inside launch_scripts/vcan-run.sh (the qemu VM on a kernel without CAN: 2 vCPUs; its
# timers tick at 4 ms unless LINEBRIDGE_VM_APPEND=tsc=reliable gives it high-resolution ones).
# Results: DIR/summary.txt (the table, the host's load average before and after) and each case's
# periods (bench-sync-jitter --out) and figures. Default DIR: BUILD/sync-jitter-<date>. BENCHMARKS.md has the figures.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
duration=40
burners=2
period_us=20000
build=$root/build
cases="loop loop-rt40 kernel"
out=""
inside=0
while [ $# -gt 0 ]; do
  case "$1" in
    --duration) duration=$2; shift 2 ;;
    --burners) burners=$2; shift 2 ;;
    --period-us) period_us=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --build) build=$(cd "$2" && pwd); shift 2 ;;
    --cases) cases=$2; shift 2 ;;
    --inside) inside=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "sync_jitter: unknown option $1" >&2; exit 2 ;;
  esac
done
py=/usr/bin/python3

if [ "$inside" = 0 ]; then
  [ -n "$out" ] || out=$build/sync-jitter-$(date +%Y%m%d-%H%M%S)
  mkdir -p "$out"
  out=$(cd "$out" && pwd)
  [ -x "$build/bench/bench-sync-jitter" ] || { echo "sync_jitter: no $build/bench/bench-sync-jitter (build it)" >&2; exit 2; }
  for b in linebridge linebridge-sim; do
    [[ " $cases " != *" loop"* ]] || [ -x "$build/bridge/app/$b" ] || { echo "sync_jitter: no $build/bridge/app/$b (build it)" >&2; exit 2; }
  done
  {
    echo "# ${LINEBRIDGE_VM_APPEND:+LINEBRIDGE_VM_APPEND=$LINEBRIDGE_VM_APPEND }bench/sync_jitter.sh --duration $duration --burners $burners --period-us $period_us --cases '$cases'"
    echo "# $(date -u +%FT%TZ) host: $(nproc) CPUs, before: $(uptime)"
  } >"$out/summary.txt"
  rc=0
  "$root/launch_scripts/vcan-run.sh" --timeout $((duration * 12 + 600)) --rw "$out" --modules can-bcm -- \
    "$0" --inside --duration "$duration" --burners "$burners" --period-us "$period_us" --build "$build" \
    --cases "$cases" --out "$out" || rc=$?
  echo "# host after: $(uptime)" >>"$out/summary.txt"
  cat "$out/summary.txt"
  exit "$rc"
fi

# --- inside the VM (or a native namespace with vcan0) ---------------------------------------------
work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT
say() { echo "$*" | tee -a "$out/summary.txt"; }

line_file() {  # $1: realtime_priority
  cat <<YAML
line: jitter
dds: {domain: 11, localhost_only: true}
buses:
  - {name: ext, interface: 'socketcan:vcan0', role: master, sync_period_ms: $((period_us / 1000)), realtime_priority: $1}
devices:
  - name: saw1
    bus: ext
    node_id: 5
    profile: cia420-4
    version: '3.1'
    heartbeat_timeout_ms: 400
    simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 6000, heartbeat_period_ms: 100}
YAML
}

# Waits until a SYNC is on vcan0 (a producer has started), at most 60 s.
await_sync() { timeout 60 candump -n 3 vcan0,080:7FF >/dev/null; }
# SYNC frames seen in $1 seconds.
count_sync() { timeout "$1" candump vcan0,080:7FF 2>/dev/null | wc -l || true; }

producer_pid=""
sim_pid=""
start_producer() {  # $1: case
  case "$1" in
    loop|loop-rt40)
      local rt=0
      [ "$1" = loop-rt40 ] && rt=40
      line_file "$rt" >"$work/line.yaml"
      "$build/bridge/app/linebridge-sim" --config "$work/line.yaml" >"$work/sim.log" 2>&1 &
      sim_pid=$!
      "$build/bridge/app/linebridge" --config "$work/line.yaml" >"$work/bridge.log" 2>&1 &
      producer_pid=$!
      ;;
    kernel)
      $py "$root/bench/bcm_sync.py" --interface vcan0 --period-us "$period_us" >"$work/bcm.log" 2>&1 &
      producer_pid=$!
      ;;
  esac
}
stop_producer() {
  kill -TERM "$producer_pid" 2>/dev/null || true
  wait "$producer_pid" 2>/dev/null || true
  if [ -n "$sim_pid" ]; then kill -TERM "$sim_pid" 2>/dev/null || true; wait "$sim_pid" 2>/dev/null || true; fi
  producer_pid="" sim_pid=""
}

say "# guest: $(nproc) CPUs, kernel $(uname -r), $duration s per case, period $period_us us"
# What the guest's timers can do: a tick-bound clock event device shows as intervals in steps of
# the tick (4 ms at HZ=250) whatever the producer.
say "# guest clocksource $(cat /sys/devices/system/clocksource/clocksource0/current_clocksource 2>/dev/null)," \
  "clock event devices $(awk '/^Clock Event Device:/ {print $4}' /proc/timer_list 2>/dev/null | sort -u | xargs)," \
  "hres_active $(awk '/hres_active/ {print $3; exit}' /proc/timer_list 2>/dev/null)"
# One line of the table from bench-sync-jitter's figures ($2) and its periods file ($3, us first).
row() {  # label figures periods
  awk -v label="$1" -v period="$period_us" '
    FNR == NR { split($0, kv, "="); v[kv[1]] = kv[2]; next }
    { n++; sum += $1; d = $1 - period; if (d < 0) d = -d; if (d > 1000) off++; if ($1 > 1.5 * period) late++ }
    END { printf "%-22s %6d %8.3f %7.0f %7.0f %8.0f %7.0f %5d %6d\n", label, n, n ? sum / n / 1000 : 0,
                 v["jitter_p50_us"], v["jitter_p99_us"], v["jitter_p999_us"], v["jitter_max_us"], off, late }' "$2" "$3"
}
say "$(printf '%-22s %6s %8s %7s %7s %8s %7s %5s %6s' case n mean_ms p50_us p99_us p99.9_us max_us '>1ms' '>1.5T')"
for load in 0 "$burners"; do
  for c in $cases; do
    burner_pids=()
    for _ in $(seq 1 "$load"); do
      sh -c 'while :; do :; done' &
      burner_pids+=($!)
    done
    pids=("${burner_pids[@]}")
    start_producer "$c"
    pids+=("$producer_pid")
    if ! await_sync; then
      say "# $c: no SYNC within 60 s"; tail -20 "$work"/*.log; exit 1
    fi
    sleep 3  # past the boot of the simulated device (its SDO burst)
    periods="$out/periods-$c-load$load.txt"
    figures="$out/figures-$c-load$load.txt"
    "$build/bench/bench-sync-jitter" --bus socketcan:vcan0 --duration "$duration" --period-us "$period_us" \
      --out "$periods" >"$figures" || true
    stop_producer
    for p in "${burner_pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
    pids=()
    say "$(row "$c burners=$load" "$figures" "$periods")"
    if [ "$c" != kernel ] && grep -qi "error\|critical" "$work/bridge.log"; then
      cp "$work/bridge.log" "$out/bridge-$c-load$load.log"
    fi
  done
done

# What a kernel SYNC does when its process stops.
lifecycle() {  # $1: signal
  $py "$root/bench/bcm_sync.py" --interface vcan0 --period-us "$period_us" >/dev/null 2>&1 &
  local p=$!
  await_sync
  kill -"$1" "$p"
  sleep 0.3
  local n
  n=$(count_sync 1)
  say "# kernel SYNC after SIG$1 of its process: $n SYNCs in the next 1 s"
  kill -KILL "$p" 2>/dev/null || true
  kill -CONT "$p" 2>/dev/null || true
  wait "$p" 2>/dev/null || true
}
lifecycle TERM
lifecycle KILL
lifecycle STOP
say "# reproduce: ${LINEBRIDGE_VM_APPEND:+LINEBRIDGE_VM_APPEND=$LINEBRIDGE_VM_APPEND }bench/sync_jitter.sh --duration $duration --burners $burners --cases '$cases'"
