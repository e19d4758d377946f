#!/usr/bin/env bash
# Runs the linebridge benchmarks and prints one table: figure, value, target, pass/fail, and the
# command that reproduces it. Everything runs inside launch_scripts/netns-run.sh (private network
# namespace and /dev/shm): the DDS participants, the virtual buses, the real `linebridge`.
#
#   launch_scripts/bench.sh [--quick] [--runs K] [--only FIGURES] [--build-dir DIR] [--no-build]
#                           [--out DIR] [--buses "1 2 4 8 ..."] [--no-pin] [--nice N] [--profile]
#                           [--no-single]
#
#   --quick          fewer samples and shorter steps (about 2 min instead of about 6 per run)
#   --runs K         measure every figure K times; the table shows the median and the range
#   --only FIGURES   comma-separated subset of: can2dds,dds2can,throughput,memory,startup,security,
#                    jitter,soak,hop,hopjitter,scrape (the last five are not in the default set: run
#                    them by name)
#   --build-dir DIR  where the build is (default build-bench); it is configured (Release) and
#                    built first unless --no-build
#   --out DIR        keep raw latencies, logs and the exact commands there (default: a new
#                    directory under /tmp, printed at the end)
#   --buses LIST     bus counts the throughput search tries, ascending (stops at the first loss)
#   --scrape-buses LIST  bus counts the scrape figure measures (default "1 8")
#   --status-publish MODE  throughput, memory, scrape: the bench line's status_publish (per_cycle,
#                    the bridge's default, or per_frame); the injector sends a SYNC before every
#                    round of the saws' TPDOs either way, as a line's master does
#   --no-pin         do not pin: by default the bridge (and what stands in for it in a floor: the
#                    bus sink, the bare DDS writer, the bare relays) runs alone on the last core and
#                    the harness (injector, subscriber, set-value writer, simulator) on the others
#   --nice N         run everything (bridge, floors, harness) at this niceness, e.g. -10 to keep a
#                    shared machine's other work from dominating the latency tails
#   --report-only    measure nothing: print the table again from the data in --out DIR
#   --jitter-rate N  frames/s of the saws' TPDOs in the jitter figure (default: full load, 8000)
#   --realtime-priority N  jitter and soak: the bridge's bus loop runs SCHED_FIFO at N (the bus key
#                    realtime_priority:), the floor's timer too (chrt -f N); default 0: normal
#   --shared-memory  every DDS participant (the bridge's: dds.shared_memory: true, and the harness's)
#                    adds Fast DDS's shared-memory transport; default: UDP on loopback only, as the
#                    bridge ships
#   --keep-awake     jitter: a SCHED_IDLE busy loop on the bridge's core, so that the core never
#                    halts between wake-ups (what idle=poll or /dev/cpu_dma_latency do on a line
#                    PC: a halted virtual CPU can wake milliseconds late); it runs only when
#                    nothing else wants the core
#   --no-single      can2dds, dds2can: measure only the split bridge (the default `--part both`),
#                    not also the one-process `--part single` beside it
#   --profile        record the bridge (both processes) with perf (call graphs) during every
#                    throughput step; perf.data and a report per step in the output directory
#
# Figures (method and limits: BENCHMARKS.md):
#   can2dds     saw TPDOs from another process on a virtual bus -> the real linebridge -> a DDS
#               subscriber in a third process. In the same run, alternating in chunks: the floor
#               (the bare bus hop and the bare Fast DDS hop, same type, QoS and rate, summed) and
#               a bare relay on the same three-process path. Overhead = bridge minus floor.
#               The bridge is the split one (`linebridge`, --part both: its bus process and the
#               DDS process it starts, both on the bridge's core); beside it, alternating, the
#               one-process `--part single` (issue 25: what the extra hop costs = split - single).
#   dds2can     a set value written by another process -> its RPDO1 on the bus. Floor: a bare
#               relay (Fast DDS listener that sends the frame); also the relay through the
#               bridge's BusLoop hand-over. The split bridge and `--part single` alternate, as in
#               can2dds. Then what a hand-over costs this machine by itself on the bridge's core
#               (bench-switch: to another thread, to another process).
#               can2dds and dds2can also report the method's own noise: the floor (can2dds: the bare
#               relay) against itself, its odd chunks minus its even ones.
#   throughput  N buses x 30 saws at 8000 frames/s each: the largest N with no frame lost and no
#               sample missing, the largest N whose frames the bridge all took, the bridge's CPU;
#               and what one bus costs a bare Fast DDS writer and a bare bus reader.
#   memory      VmRSS / VmHWM of the bridge with 8 buses x 30 saws under full load.
#   startup     process start -> first status sample at an already running subscriber; when the
#               subscriber discovered the bridge's DDS participant and its status writers; the CPU
#               each process used until every saw was online (bus, DDS, simulator, subscriber).
#   jitter      SYNC period jitter (p50/p99/p99.9/max deviation from 20 ms) of a master bridge with
#               30 saws: idle (no load: the unloaded figure); then at full load (8000 frames/s,
#               --jitter-rate) with an EMCY burst (1000/s), three ways: alone; with an emergency
#               subscriber that freezes (SIGSTOP: it neither reads nor acknowledges); recording to
#               a slow disk (a FIFO drained at 16 KiB/s). Beside them the floor: a bare periodic
#               timer on the bridge's core (bench-timer-floor), how steady this machine can be at all.
#               Every figure also between host stalls: a sentinel thread on the bridge's core, one
#               realtime priority above it, marks where the host did not run that core at all
#               (bench/stall_sentinel.hpp); the periods those stalls touched are left out there.
#               Not with --no-pin or on one core: the bridge then has no core of its own to watch.
#   soak        resident memory and open file descriptors of the bridge sampled every 10 s during a
#               flood (full load, EMCY burst, hostile frames on every identifier, and three
#               applications calling services back to back plus two writing set values as fast as
#               they go, hostile requests among them), 10 minutes (2 with --quick): start, end,
#               highest; the SYNCs seen meanwhile and what the request flood got answered.
#   security    DDS Security's cost, secured and unsecured side by side, alternating in chunks:
#               the bare Fast DDS hop, CAN->DDS and DDS->CAN through the bridge, and start-up
#               (1 saw) of a line secured by launch_scripts/pki.sh (PKI-DH, access control,
#               discovery, liveliness, metadata and data ENCRYPT) against the same line unsecured.
#   hop         the channel between the bus and the DDS process by itself (bench-channel-hop:
#               link::BusChannel -> link::DdsChannel and back, one 128-byte sample in flight,
#               p50/p99 one way and round trip); the same through iceoryx when bench-iceoryx-hop
#               is built (-DLINEBRIDGE_BENCH_ICEORYX=ON) and iox-roudi is installed.
#   hopjitter   SYNC jitter of a secured master line (30 saws at full load) with the DDS side under
#               stress, the split bridge and `--part single` alternating: load alone; 20 observer
#               participants on every status topic (bench-observers); the forged-discovery flood
#               (bench-forged-announcements, 3,000 announcements at 2,000/s, repeated).
#   scrape      what /metrics costs (issue 43): the bridge's CPU (both processes) at full load (N
#               buses x 30 saws at 8000 frames/s, the throughput figure's step), its observability
#               listener on as by default (127.0.0.1:9420), alternating in chunks: not scraped, and
#               scraped every second (curl GET /metrics, then 1 s, from the harness's core(s)); the
#               scrapes answered and the size of the answer; and the CPU time one scrape costs the
#               bridge (100 back to back once the load is over, less as long idle).
set -euo pipefail

usage() { sed -n '2,/^set -euo/p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'; exit 2; }

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
orig_args=("$@")
quick=0
runs=1
only="can2dds,dds2can,throughput,memory,startup,security"
build_dir="$root/build-bench"
do_build=1
out_dir=""
buses_list=""
scrape_buses=""
status_publish=""
pin=1
niceness=0
profile=0
single=1
jitter_rate=""
rt_priority=0
keep_awake=0
report_only=0
while (($#)); do
  case "$1" in
    --quick) quick=1 ;;
    --runs) runs=${2:?}; shift ;;
    --only) only=${2:?}; shift ;;
    --build-dir) build_dir=$(realpath -m "${2:?}"); shift ;;
    --no-build) do_build=0 ;;
    --out) out_dir=$(realpath -m "${2:?}"); shift ;;
    --buses) buses_list=${2:?}; shift ;;
    --scrape-buses) scrape_buses=${2:?}; shift ;;
    --status-publish) status_publish=${2:?}; shift ;;
    --no-pin) pin=0 ;;
    --nice) niceness=${2:?}; shift ;;
    --profile) profile=1 ;;
    --no-single) single=0 ;;
    --jitter-rate) jitter_rate=${2:?}; shift ;;
    --realtime-priority) rt_priority=${2:?}; shift ;;
    --keep-awake) keep_awake=1 ;;
    --shared-memory) export LINEBRIDGE_BENCH_SHARED_MEMORY=1 ;;
    --report-only) report_only=1; do_build=0 ;;
    -h|--help) usage ;;
    *) echo "bench.sh: unknown argument $1" >&2; usage ;;
  esac
  shift
done
[[ $runs =~ ^[1-9][0-9]*$ ]] || { echo "bench.sh: --runs takes a positive number" >&2; exit 2; }
[[ $rt_priority =~ ^[0-9]+$ ]] && ((rt_priority <= 99)) || { echo "bench.sh: --realtime-priority takes 0..99" >&2; exit 2; }
((!keep_awake || pin)) || { echo "bench.sh: --keep-awake keeps the bridge's core awake: it needs pinning (no --no-pin)" >&2; exit 2; }
for f in ${only//,/ }; do
  [[ $f =~ ^(can2dds|dds2can|throughput|memory|startup|security|jitter|soak|hop|hopjitter|scrape)$ ]] || { echo "bench.sh: unknown figure $f" >&2; exit 2; }
done

# Outside the namespace: build (no DDS here), then re-enter through the wrapper.
if [ "${LINEBRIDGE_NETNS:-}" != "1" ]; then
  if ((do_build)); then
    "$root/launch_scripts/setup.sh" >&2
    if [ ! -f "$build_dir/CMakeCache.txt" ]; then
      # GCC 12 at -O3 reports false warnings inside libstdc++, not errors here: -Wrestrict in its
      # string concatenation (GCC bug 105329; bridge/can/candump_log.cpp) and -Wstringop-overflow
      # in vector::push_back's reallocation (GCC bug 106199; bridge/canopen/pdo_parameters.cpp).
      # Every other warning stays an error.
      cmake -S "$root" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DLINEBRIDGE_WERROR=ON \
        "-DCMAKE_CXX_FLAGS=-Wno-error=restrict -Wno-error=stringop-overflow" >&2
    fi
    cmake --build "$build_dir" --target linebridge linebridge-sim linebridge-security bench-config bench-inject bench-can-sink \
      bench-status-pub bench-status-sub bench-setpoint bench-relay bench-can-relay bench-startup bench-stats \
      bench-sync-jitter bench-frozen-reader bench-timer-floor bench-request-flood bench-channel-hop bench-observers bench-switch \
      bench-forged-announcements >&2
    # The iceoryx comparison, when that build has it (-DLINEBRIDGE_BENCH_ICEORYX=ON).
    if grep -q '^LINEBRIDGE_BENCH_ICEORYX:BOOL=ON' "$build_dir/CMakeCache.txt"; then cmake --build "$build_dir" --target bench-iceoryx-hop >&2; fi
  fi
  [ -n "$out_dir" ] || out_dir=$(mktemp -d /tmp/linebridge-bench.XXXXXX)
  mkdir -p "$out_dir"
  exec nice -n "$niceness" "$root/launch_scripts/netns-run.sh" "$0" "${orig_args[@]}" --no-build --build-dir "$build_dir" --out "$out_dir"
fi

# ------------------------------------------------------------------------------------------------
# Settings. Full: >= 100,000 latency samples per set (the issue's minimum); quick: a smoke run.
bin="$build_dir/bench"
bridge_bin="$build_dir/bridge/app/linebridge"
sim_bin="$build_dir/bridge/app/linebridge-sim"
for b in "$bridge_bin" "$sim_bin" "$bin/bench-inject" "$bin/bench-stats"; do
  [ -x "$b" ] || { echo "bench.sh: $b missing: build first (or drop --no-build)" >&2; exit 1; }
done
devices=30
lat_rate=3000            # 30 saws x (TPDO1 + TPDO2) every 20 ms SYNC
full_rate=8000           # frames/s of a saturated 1 Mbit/s bus
# Latency sets are measured in chunks, bridge and floor alternating, so that a burst of load from
# elsewhere on a shared machine hits all of them alike instead of one whole set.
if ((quick)); then
  chunks=2; lat_samples=5000; lat_warmup=600; sp_samples=500; sp_warmup=50; step_s=4; startup_reps="3 1"
  jitter_s=15; soak_s=120
  quick_flag=" --quick"
else
  chunks=5; lat_samples=20000; lat_warmup=600; sp_samples=1000; sp_warmup=100; step_s=10; startup_reps="10 3"
  jitter_s=60; soak_s=600
  quick_flag=""
fi
[ -n "$buses_list" ] || buses_list="1 2 3 4 6 8 10 12 16"
mem_buses=8
[ -n "$scrape_buses" ] || scrape_buses="1 $mem_buses"
cores=$(nproc)
pin_cmd=()      # the bridge (and what stands for it in a floor): the last core, alone
harness_cmd=()  # the load and the readers: every other core, so they never take the bridge's
if ((pin)) && ((cores >= 2)); then
  pin_cmd=(taskset -c $((cores - 1)))
  harness_cmd=(taskset -c 0-$((cores - 2)))
fi
# The jitter figure's host-stall sentinel (bench/stall_sentinel.hpp): on the bridge's core, one
# realtime priority above the bridge's loop (or the floor's timer).
# Without pinning the bridge has no core of its own to watch: no sentinel, and the table says so.
sentinel_args=()
((${#pin_cmd[@]} == 0)) || sentinel_args=(--sentinel-cpu $((cores - 1)) --sentinel-priority $((rt_priority + 1)))
sentinel=$((${#sentinel_args[@]} > 0))
clk_tck=$(getconf CLK_TCK)
mkdir -p "$out_dir"
commands="$out_dir/commands.txt"
: >"$commands"

# ------------------------------------------------------------------------------------------------
# Processes: every one we start is remembered by PID and stopped by PID, nothing else.
declare -a started=()
cleanup() {
  local pid
  for pid in "${started[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${started[@]}"; do wait "$pid" 2>/dev/null || true; done
}
trap cleanup EXIT

# start LOG CMD... : runs CMD in the background (stdout to LOG.out, stderr to LOG.err); sets $pid.
start() {
  local log=$1; shift
  printf '%s\n' "$*" >>"$commands"
  "$@" >"$log.out" 2>"$log.err" &
  pid=$!
  started+=("$pid")
}

# wait_file FILE PID [SECONDS]: until FILE exists; fails if PID died or the time ran out.
wait_file() {
  local file=$1 who=$2 limit=${3:-120} waited=0
  while [ ! -e "$file" ]; do
    if ! kill -0 "$who" 2>/dev/null; then echo "bench.sh: process $who exited before $file" >&2; return 1; fi
    sleep 0.02
    waited=$((waited + 1))
    if ((waited > limit * 50)); then echo "bench.sh: timeout waiting for $file" >&2; return 1; fi
  done
}

# finish PID: waits for it and returns its exit status without tripping set -e.
finish() { local rc=0; wait "$1" || rc=$?; return $rc; }
stop() { kill -TERM "$1" 2>/dev/null || true; finish "$1" || true; }

# The PIDs of a process's children (space-separated).
children() { cat /proc/"$1"/task/*/children 2>/dev/null; }
# utime + stime in ticks; empty when the process is gone.
cpu_ticks() { awk '{ sub(/.*\) /, ""); print $12 + $13 }' "/proc/$1/stat" 2>/dev/null || true; }
# The same for a process and its children (the split bridge: the bus process and its DDS process).
tree_ticks() {
  local t c x
  t=$(cpu_ticks "$1")
  [ -n "$t" ] || return 0
  for c in $(children "$1"); do
    x=$(cpu_ticks "$c"); t=$((t + ${x:-0}))
  done
  echo "$t"
}
# A process and its children as perf's -p wants them: "PID,CHILD,..." (the split bridge's two).
tree_pids() {
  local p=$1 c
  for c in $(children "$1"); do p+=",$c"; done
  echo "$p"
}
# bridge_part bridge|single: the bridge's extra arguments (bridge: none, the default split).
bridge_part() { [ "$1" != single ] || echo "--part single"; }
# cpu_percent T0_TICKS T1_TICKS T0_NS T1_NS: % of one core over the interval (empty if unknown).
cpu_percent() {
  [ -n "$1" ] && [ -n "$2" ] || return 0
  awk -v a="$1" -v b="$2" -v s="$3" -v e="$4" -v hz="$clk_tck" 'BEGIN { printf "%.1f", (b - a) / hz / ((e - s) / 1e9) * 100 }'
}
now_ns() { date +%s%N; }
# mib KIB: MiB with one decimal; nothing when the figure is missing (so no verdict, not 0 and a pass).
mib() { awk -v k="$1" 'BEGIN { if (k != "") printf "%.1f", k / 1024 }'; }
mem_kib() { awk -v k="$2:" '$1 == k { print $2 }' "/proc/$1/status"; }
get() { sed -n "s/^$2=//p" "$1" | tail -1; }  # get FILE KEY (key=value reports)

# The method's own noise: one floor set against itself, its odd chunks minus its even chunks (the
# same program, alternating with the others like every set). What a difference between two sets
# can show at all on this host: a bridge-minus-floor figure within this of zero is no difference.
self_noise() {  # SET_DIR FILE KEY_PREFIX: appends KEY_PREFIX_p50_us, _p99_us, _p999_us to $vals
  local dir=$1 file=$2 key=$3 c odd=() even=()
  for ((c = 1; c <= chunks; c++)); do
    if ((c % 2)); then odd+=("$dir/c$c/$file"); else even+=("$dir/c$c/$file"); fi
  done
  ((${#even[@]} > 0)) || return 0
  cat "${odd[@]}" >"$dir/odd.lat"
  cat "${even[@]}" >"$dir/even.lat"
  "$bin/bench-stats" overhead "$dir/odd.lat" "$dir/even.lat" | sed -n "s/^overhead_/${key}_/p" >>"$vals"
}

domain=10
# The security figure's secured steps: every participant gets an identity of this PKI (pki.sh), and
# all of them use its one domain, since the governance and the grants name it.
secure_pki=""
secure_domain=200
next_domain() {
  if [ -n "$secure_pki" ]; then domain=$secure_domain; else domain=$((domain + 1)); fi
}
# secured IDENTITY: sets $sec to the bench programs' security options (empty when unsecured), and
# $sec_cfg to bench-config's.
secured() {
  sec=(); sec_cfg=()
  [ -z "$secure_pki" ] || { sec=(--pki "$secure_pki" --identity "$1"); sec_cfg=(--pki "$secure_pki"); }
}

# ------------------------------------------------------------------------------------------------
# One run of each figure. Each writes key=value lines to $vals (appended), raw data to its dir.

bus_floor() {  # DIR PREFIX
  local d=$1 p=$2 inj
  start "$d/inject" "${harness_cmd[@]}" "$bin/bench-inject" --buses 1 --devices $devices --rate $lat_rate --count $((lat_samples + lat_warmup)) \
    --prefix "$p" --ready "$d/inject.ready" --go "$d/go" --stop "$d/stop" --linger 120
  inj=$pid
  wait_file "$d/inject.ready" $inj
  start "$d/sink" "${pin_cmd[@]}" "$bin/bench-can-sink" --prefix "$p" --expect $((lat_samples + lat_warmup)) --warmup $lat_warmup \
    --ready "$d/sink.ready" --out "$d/bus.lat"
  local sink=$pid
  wait_file "$d/sink.ready" $sink
  touch "$d/go"
  finish $sink || echo "bench.sh: bus floor: frames missing (see $d/sink.out)" >&2
  touch "$d/stop"
  finish $inj || true
}

dds_floor() {  # DIR
  local d=$1 sub pub
  next_domain
  secured observer
  start "$d/sub" "${harness_cmd[@]}" "$bin/bench-status-sub" --buses 1 --devices $devices --domain $domain --expect $((lat_samples + lat_warmup)) \
    --warmup $lat_warmup --ready "$d/sub.ready" --out "$d/dds.lat" "${sec[@]}"
  sub=$pid
  secured bridge  # a bare writer of the bridge's status topics
  start "$d/pub" "${pin_cmd[@]}" "$bin/bench-status-pub" --devices $devices --domain $domain --rate $lat_rate --count $((lat_samples + lat_warmup)) \
    --ready "$d/pub.ready" --go "$d/go" --stop "$d/stop" --linger 120 "${sec[@]}"
  pub=$pid
  wait_file "$d/sub.ready" $sub
  wait_file "$d/pub.ready" $pub
  touch "$d/go"
  finish $sub || echo "bench.sh: DDS floor: samples missing (see $d/sub.out)" >&2
  touch "$d/stop"
  finish $pub || true
}

# path_can2dds DIR PREFIX bridge|single|relay: injector -> the bridge (split; or --part single; or
# the bare relay) -> subscriber.
path_can2dds() {
  local d=$1 p=$2 what=$3 inj sub br
  next_domain
  secured observer
  "$bin/bench-config" --buses 1 --devices $devices --domain $domain --prefix "$p" --role monitor "${sec_cfg[@]}" >"$d/line.yaml"
  start "$d/inject" "${harness_cmd[@]}" "$bin/bench-inject" --buses 1 --devices $devices --rate $lat_rate --count $((lat_samples + lat_warmup)) \
    --prefix "$p" --ready "$d/inject.ready" --go "$d/go" --stop "$d/stop" --linger 120
  inj=$pid
  wait_file "$d/inject.ready" $inj
  local diag=()
  [ "$what" = relay ] || diag=(--diagnostics)
  start "$d/sub" "${harness_cmd[@]}" "$bin/bench-status-sub" --buses 1 --devices $devices --domain $domain --expect $((lat_samples + lat_warmup)) \
    --warmup $lat_warmup "${diag[@]}" --ready "$d/sub.ready" --out "$d/$what.lat" "${sec[@]}"
  sub=$pid
  if [ "$what" = relay ]; then
    start "$d/relay" "${pin_cmd[@]}" "$bin/bench-can-relay" --prefix "$p" --devices $devices --domain $domain
  else
    start "$d/bridge" "${pin_cmd[@]}" "$bridge_bin" --config "$d/line.yaml" $(bridge_part "$what")
  fi
  br=$pid
  wait_file "$d/sub.ready" $sub
  sleep 0.5
  local c0 t0 c1 t1
  c0=$(tree_ticks $br); t0=$(now_ns)
  touch "$d/go"
  while [ ! -s "$d/inject.out" ] && kill -0 $inj 2>/dev/null; do sleep 0.05; done
  c1=$(tree_ticks $br); t1=$(now_ns)
  finish $sub || echo "bench.sh: can2dds: samples missing (see $d/sub.out)" >&2
  touch "$d/stop"
  finish $inj || true
  stop $br
  local stamped
  stamped=$(get "$d/sub.out" sub_stamped)
  echo "chunk_${what}_cpu_pct=$(cpu_percent "$c0" "$c1" "$t0" "$t1")" >>"$vals"
  echo "chunk_${what}_missing=$(( lat_samples + lat_warmup - ${stamped:-0} ))" >>"$vals"
}

fig_can2dds() {  # RUN
  local d="$out_dir/can2dds/run$1" c
  vals="$d/values"; mkdir -p "$d"; : >"$vals"
  for ((c = 1; c <= chunks; c++)); do
    mkdir -p "$d/bus/c$c" "$d/dds/c$c" "$d/bridge/c$c" "$d/relay/c$c" "$d/single/c$c"
    bus_floor "$d/bus/c$c" "c2d-bus-$1-$c"
    dds_floor "$d/dds/c$c"
    path_can2dds "$d/bridge/c$c" "c2d-br-$1-$c" bridge
    ((!single)) || path_can2dds "$d/single/c$c" "c2d-single-$1-$c" single
    path_can2dds "$d/relay/c$c" "c2d-relay-$1-$c" relay
  done
  local set
  for set in bus dds bridge relay; do cat "$d/$set"/c*/$set.lat >"$d/$set.lat"; done
  if ((single)); then
    cat "$d"/single/c*/single.lat >"$d/single.lat"
    # What the extra hop costs: the split bridge over the one-process bridge, same run.
    "$bin/bench-stats" overhead "$d/bridge.lat" "$d/single.lat" | sed -n 's/^floor_/can2dds_single_/p; s/^overhead_/can2dds_split_over_single_/p' >>"$vals"
    sed -n "s/^chunk_single_cpu_pct=//p" "$vals" | awk '{ s += $1 } END { if (NR) printf "can2dds_single_cpu_pct=%.1f\n", s / NR }' >>"$vals"
    sed -n "s/^chunk_single_missing=//p" "$vals" | awk '{ s += $1 } END { printf "can2dds_single_missing=%d\n", s }' >>"$vals"
  fi
  "$bin/bench-stats" overhead "$d/bridge.lat" "$d/bus.lat" "$d/dds.lat" | sed 's/^/can2dds_/' >>"$vals"
  "$bin/bench-stats" overhead "$d/bridge.lat" "$d/relay.lat" | sed -n 's/^floor_/can2dds_relay_/p; s/^overhead_/can2dds_over_relay_/p' >>"$vals"
  self_noise "$d/relay" relay.lat can2dds_relay_self
  "$bin/bench-stats" summary "$d/bus.lat" | sed 's/^lat_/can2dds_bus_/' >>"$vals"
  "$bin/bench-stats" summary "$d/dds.lat" | sed 's/^lat_/can2dds_dds_/' >>"$vals"
  # Per chunk: CPU (mean over chunks) and missing samples (sum).
  for set in bridge relay; do
    sed -n "s/^chunk_${set}_cpu_pct=//p" "$vals" | awk -v k="can2dds_${set}_cpu_pct" '{ s += $1 } END { if (NR) printf "%s=%.1f\n", k, s / NR }' >>"$vals"
    sed -n "s/^chunk_${set}_missing=//p" "$vals" | awk -v k="can2dds_${set}_missing" '{ s += $1 } END { printf "%s=%d\n", k, s }' >>"$vals"
  done
}

setpoint_bridge() {  # DIR PREFIX [bridge|single]: the bridge (split, or --part single) in the master role (the saw booted and online, as
  # set values require), RPDO1 event-driven so the frame leaves when the value is applied instead
  # of at the next SYNC.
  local d=$1 p=$2 what=${3:-bridge} sp sim br
  next_domain
  secured engineer  # set values of every device
  "$bin/bench-config" --buses 1 --devices 1 --domain $domain --prefix "$p" --role master --rpdo-event \
    --realtime-priority $rt_priority "${sec_cfg[@]}" >"$d/line.yaml"
  start "$d/setpoint" "${harness_cmd[@]}" "$bin/bench-setpoint" --prefix "$p" --domain $domain --count $sp_samples --warmup $sp_warmup \
    --ready "$d/setpoint.ready" --go "$d/go" --out "$d/$what.lat" "${sec[@]}"
  sp=$pid
  wait_file "$d/setpoint.ready" $sp
  start "$d/sim" "${harness_cmd[@]}" "$sim_bin" --config "$d/line.yaml"
  sim=$pid
  start "$d/bridge" "${pin_cmd[@]}" "$bridge_bin" --config "$d/line.yaml" $(bridge_part "$what")
  br=$pid
  touch "$d/go"
  finish $sp || echo "bench.sh: dds2can: set values lost (see $d/setpoint.out)" >&2
  stop $br
  stop $sim
  local lost
  lost=$(get "$d/setpoint.out" setpoint_lost)
  if [ "$what" = single ]; then echo "chunk_single_lost=${lost:-$sp_samples}" >>"$vals"; else echo "chunk_lost=${lost:-$sp_samples}" >>"$vals"; fi
}

setpoint_relay() {  # DIR PREFIX [--handoff]: the same client against a bare relay
  local d=$1 p=$2 sp relay
  shift 2
  next_domain
  start "$d/setpoint" "${harness_cmd[@]}" "$bin/bench-setpoint" --prefix "$p" --domain $domain --count $sp_samples --warmup $sp_warmup \
    --ready "$d/setpoint.ready" --go "$d/go" --out "$d/relay.lat"
  sp=$pid
  wait_file "$d/setpoint.ready" $sp
  local rt=()
  ((rt_priority == 0)) || rt=(chrt -f $rt_priority)
  start "$d/relay" "${pin_cmd[@]}" "${rt[@]}" "$bin/bench-relay" --prefix "$p" --domain $domain --ready "$d/relay.ready" "$@"
  relay=$pid
  wait_file "$d/relay.ready" $relay
  touch "$d/go"
  finish $sp || echo "bench.sh: dds2can floor: set values lost (see $d/setpoint.out)" >&2
  stop $relay
}

fig_dds2can() {  # RUN
  local d="$out_dir/dds2can/run$1" c
  vals="$d/values"; mkdir -p "$d"; : >"$vals"
  for ((c = 1; c <= chunks; c++)); do
    mkdir -p "$d/bridge/c$c" "$d/relay/c$c" "$d/handoff/c$c" "$d/single/c$c"
    setpoint_bridge "$d/bridge/c$c" "d2c-br-$1-$c"
    ((!single)) || setpoint_bridge "$d/single/c$c" "d2c-single-$1-$c" single
    setpoint_relay "$d/relay/c$c" "d2c-relay-$1-$c"
    setpoint_relay "$d/handoff/c$c" "d2c-handoff-$1-$c" --handoff
  done
  cat "$d"/bridge/c*/bridge.lat >"$d/bridge.lat"
  cat "$d"/relay/c*/relay.lat >"$d/relay.lat"
  cat "$d"/handoff/c*/relay.lat >"$d/handoff.lat"
  "$bin/bench-stats" overhead "$d/bridge.lat" "$d/relay.lat" | sed 's/^/dds2can_/' >>"$vals"
  "$bin/bench-stats" overhead "$d/handoff.lat" "$d/relay.lat" | sed -n 's/^bridge_/dds2can_handoff_/p' >>"$vals"
  self_noise "$d/relay" relay.lat dds2can_floor_self
  sed -n 's/^chunk_lost=//p' "$vals" | awk '{ s += $1 } END { printf "dds2can_lost=%d\n", s }' >>"$vals"
  if ((single)); then
    cat "$d"/single/c*/single.lat >"$d/single.lat"
    "$bin/bench-stats" overhead "$d/bridge.lat" "$d/single.lat" | sed -n 's/^floor_/dds2can_single_/p; s/^overhead_/dds2can_split_over_single_/p' >>"$vals"
    sed -n 's/^chunk_single_lost=//p' "$vals" | awk '{ s += $1 } END { printf "dds2can_single_lost=%d\n", s }' >>"$vals"
  fi
  # What this machine charges for the two hand-overs themselves, on the bridge's core: to another
  # thread (the one-process bridge's listener waking its bus loop) and to another process (the
  # split's DDS process waking the bus process).
  printf '%s\n' "${pin_cmd[*]} $bin/bench-switch" >>"$commands"
  "${pin_cmd[@]}" "$bin/bench-switch" 2>"$d/switch.err" | sed 's/^/dds2can_/' >>"$vals" || true
}

# throughput_step DIR N [scrape] -> key=value lines in DIR/step, exit 0 when nothing was lost.
# scrape: /metrics of the bridge's DDS process is fetched every second meanwhile (the scrape figure).
throughput_step() {
  local d=$1 n=$2 scrape=${3:-} inj sub br scraper="" count=$((full_rate * step_s))
  mkdir -p "$d"
  next_domain
  local p="tp-$n-$RANDOM"
  "$bin/bench-config" --buses "$n" --devices $devices --domain $domain --prefix "$p" --role monitor \
    ${status_publish:+--status-publish "$status_publish"} >"$d/line.yaml"
  start "$d/inject" "${harness_cmd[@]}" "$bin/bench-inject" --buses "$n" --devices $devices --rate $full_rate --count $count \
    --sync --prefix "$p" --ready "$d/inject.ready" --go "$d/go" --stop "$d/stop" --linger 120
  inj=$pid
  wait_file "$d/inject.ready" $inj
  start "$d/sub" "${harness_cmd[@]}" "$bin/bench-status-sub" --buses "$n" --devices $devices --domain $domain --expect $((count * n)) \
    --diagnostics --ready "$d/sub.ready" --out "$d/loaded.lat" --timeout $((step_s * 4 + 120))
  sub=$pid
  start "$d/bridge" "${pin_cmd[@]}" "$bridge_bin" --config "$d/line.yaml"
  br=$pid
  wait_file "$d/sub.ready" $sub 180
  if [ -n "$scrape" ]; then
    # One line per scrape: HTTP status, bytes, seconds. Before the measured window, so it spans it.
    start "$d/scraper" "${harness_cmd[@]}" bash -c 'while :; do
      curl -s -o /dev/null --max-time 1 -w "%{http_code} %{size_download} %{time_total}\n" http://127.0.0.1:9420/metrics
      sleep 1; done'
    scraper=$pid
  fi
  sleep 0.5
  local c0 s0 i0 t0 c1 s1 i1 t1
  # The bridge's CPU is both its processes' (the DDS process does the Fast DDS writes).
  c0=$(tree_ticks $br); s0=$(cpu_ticks $sub); i0=$(cpu_ticks $inj); t0=$(now_ns)
  touch "$d/go"
  local perf_pid=""
  if ((profile)); then
    local pids
    pids=$(tree_pids $br)  # the bus process and its DDS process
    printf '%s\n' "perf record -F 1999 --call-graph dwarf,16384 -o $d/perf.data -p $pids -- sleep $((step_s / 2))" >>"$commands"
    perf record -F 1999 --call-graph dwarf,16384 -o "$d/perf.data" -p "$pids" -- sleep $((step_s / 2)) >"$d/perf.log" 2>&1 &
    perf_pid=$!
  fi
  while [ ! -s "$d/inject.out" ] && kill -0 $inj 2>/dev/null; do sleep 0.05; done
  c1=$(tree_ticks $br); s1=$(cpu_ticks $sub); i1=$(cpu_ticks $inj); t1=$(now_ns)
  local rss hwm pss
  if [ -n "$perf_pid" ]; then
    finish $perf_pid || true
    perf report -i "$d/perf.data" --no-children --sort pid --stdio -g none 2>/dev/null | grep '%' >"$d/profile-threads.txt" || true
    perf report -i "$d/perf.data" --no-children --sort dso --stdio -g none 2>/dev/null | grep '%' >"$d/profile-dso.txt" || true
    perf report -i "$d/perf.data" --children --sort sym --stdio -g none 2>/dev/null | grep '%' | head -80 >"$d/profile-sym.txt" || true
  fi
  finish $sub || true
  # The bus process and its DDS process together (bench/proc_stats.hpp read_tree_memory): VmRSS and
  # VmHWM summed count a shared library's pages in each; Pss counts each page once, the target's figure.
  "$bin/bench-stats" memory $br >"$d/memory"
  rss=$(get "$d/memory" rss_kib); hwm=$(get "$d/memory" hwm_kib); pss=$(get "$d/memory" pss_kib)
  local scrape_cpu_ms=""
  if [ -n "$scraper" ]; then
    # What one scrape costs the bridge in CPU time, which a shared machine's load moves far less
    # than a share of a core: both processes' CPU over 100 scrapes back to back (the load is over),
    # less their CPU over as long idle just before, over 100.
    stop $scraper
    local k0 k1 k2 e0 e1 e2
    k0=$(tree_ticks $br); e0=$(now_ns)
    sleep 2
    k1=$(tree_ticks $br); e1=$(now_ns)
    "${harness_cmd[@]}" bash -c 'for ((i = 0; i < 100; i++)); do curl -s -o /dev/null --max-time 5 http://127.0.0.1:9420/metrics; done' || true
    k2=$(tree_ticks $br); e2=$(now_ns)
    scrape_cpu_ms=$(awk -v k0="$k0" -v k1="$k1" -v k2="$k2" -v e0="$e0" -v e1="$e1" -v e2="$e2" -v hz="$clk_tck" \
      'BEGIN { if (k0 == "" || k2 == "" || e1 <= e0) exit; busy = (k2 - k1) - (k1 - k0) * (e2 - e1) / (e1 - e0)
               printf "%.2f", busy / hz * 1000 / 100 }')
  fi
  touch "$d/stop"
  finish $inj || true
  stop $br
  # What the bus process's channel said at its stop (link::BusChannel::stop): state samples a newer
  # one replaced before they were sent, i.e. lost because the DDS process lagged (split bridge only).
  local superseded
  superseded=$(grep -hoE '[0-9]+ state sample\(s\) replaced' "$d/bridge.out" "$d/bridge.err" 2>/dev/null | tail -1 | cut -d' ' -f1)
  local sent dropped rate frames_in err stamped syncs
  sent=$(get "$d/inject.out" inject_frames_sent); dropped=$(get "$d/inject.out" inject_tx_dropped)
  syncs=$(get "$d/inject.out" inject_syncs_sent)
  rate=$(get "$d/inject.out" inject_rate_per_bus)
  frames_in=$(get "$d/sub.out" bridge_frames_in); err=$(get "$d/sub.out" bridge_error_frames)
  stamped=$(get "$d/sub.out" sub_stamped)
  {
    echo "buses=$n"
    echo "offered=$((count * n))"
    echo "sent=${sent:-0}"
    echo "harness_dropped=${dropped:-0}"
    echo "rate_per_bus=${rate:-0}"
    echo "bridge_frames_in=${frames_in:-0}"
    echo "bridge_overflows=${err:-0}"
    echo "samples=${stamped:-0}"
    echo "samples_published=$(get "$d/sub.out" sub_samples)"
    echo "syncs=${syncs:-0}"
    echo "samples_per_s_per_bus=$(awk -v s="$(get "$d/sub.out" sub_samples)" -v t=$step_s -v n="$n" 'BEGIN { if (s != "") printf "%.0f", s / t / n }')"
    echo "loaded_last_p50_us=$(get "$d/sub.out" sub_last_p50_us)"
    echo "bridge_cpu_pct=$(cpu_percent "$c0" "$c1" "$t0" "$t1")"
    echo "sub_cpu_pct=$(cpu_percent "$s0" "$s1" "$t0" "$t1")"
    echo "inject_cpu_pct=$(cpu_percent "$i0" "$i1" "$t0" "$t1")"
    echo "rss_kib=${rss:-0}"
    echo "hwm_kib=${hwm:-0}"
    echo "pss_kib=${pss:-0}"
    echo "loaded_p50_us=$(get "$d/sub.out" sub_p50_us)"
    echo "loaded_p99_us=$(get "$d/sub.out" sub_p99_us)"
    echo "channel_superseded=${superseded:-}"
    if [ -n "$scrape" ]; then
      echo "scrapes=$(wc -l <"$d/scraper.out")"
      echo "scrapes_ok=$(awk '$1 == 200' "$d/scraper.out" | wc -l)"
      echo "scrape_kib=$(awk '$1 == 200 { b += $2; n++ } END { if (n) printf "%.0f", b / n / 1024 }' "$d/scraper.out")"
      echo "scrape_ms=$(awk '$1 == 200 { t += $3; n++ } END { if (n) printf "%.1f", t / n * 1000 }' "$d/scraper.out")"
      echo "scrape_cpu_ms=$scrape_cpu_ms"
    fi
  } >"$d/step"
  # Frames: everything offered was sent at the full rate and taken by the bridge (no overflow).
  local frames_ok=0
  [ "${sent:-0}" = "$((count * n))" ] && [ "${frames_in:-x}" = "$((sent + ${syncs:-0}))" ] && [ "${err:-x}" = 0 ] &&
    awk -v r="${rate:-0}" -v t=$full_rate 'BEGIN { exit !(r >= 0.99 * t) }' && frames_ok=1
  echo "frames_ok=$frames_ok" >>"$d/step"
  ((frames_ok)) && [ "${stamped:-x}" = "$sent" ]
}

# What one bus at full load costs without the bridge, on the core the bridge gets: a bare Fast DDS
# writer of the 30 status topics at the frame rate, and a bare reader of the bus.
throughput_floor() {  # DIR
  local d=$1 sub pub inj sink count=$((full_rate * step_s)) p="tpf-$RANDOM"
  mkdir -p "$d/dds" "$d/bus"
  next_domain
  start "$d/dds/sub" "$bin/bench-status-sub" --buses 1 --devices $devices --domain $domain --expect $count \
    --ready "$d/dds/sub.ready" --idle 2
  sub=$pid
  start "$d/dds/pub" "${pin_cmd[@]}" "$bin/bench-status-pub" --devices $devices --domain $domain --rate $full_rate \
    --count $count --ready "$d/dds/pub.ready" --go "$d/dds/go" --stop "$d/dds/stop" --linger 120
  pub=$pid
  wait_file "$d/dds/sub.ready" $sub
  wait_file "$d/dds/pub.ready" $pub
  touch "$d/dds/go"
  finish $sub || true
  touch "$d/dds/stop"
  finish $pub || true
  start "$d/bus/inject" "$bin/bench-inject" --buses 1 --devices $devices --rate $full_rate --count $count \
    --prefix "$p" --ready "$d/bus/inject.ready" --go "$d/bus/go" --stop "$d/bus/stop" --linger 120
  inj=$pid
  wait_file "$d/bus/inject.ready" $inj
  start "$d/bus/sink" "${pin_cmd[@]}" "$bin/bench-can-sink" --prefix "$p" \
    --expect $count --ready "$d/bus/sink.ready"
  sink=$pid
  wait_file "$d/bus/sink.ready" $sink
  touch "$d/bus/go"
  finish $sink || true
  touch "$d/bus/stop"
  finish $inj || true
  echo "throughput_floor_dds_cpu_pct=$(get "$d/dds/pub.out" pub_cpu_pct)" >>"$vals"
  echo "throughput_floor_bus_cpu_pct=$(get "$d/bus/sink.out" sink_cpu_pct)" >>"$vals"
  echo "throughput_floor_dds_missing=$(get "$d/dds/sub.out" sub_missing)" >>"$vals"
}

fig_throughput() {  # RUN
  local d="$out_dir/throughput/run$1" n best=0 best_cpu="" per_bus=""
  mkdir -p "$d"
  vals="$d/values"; : >"$vals"
  throughput_floor "$d/floor"
  # The search goes on while the bridge takes every frame, so the table can tell a subscriber that
  # falls behind (samples missing) from a bridge that does (frames lost).
  local best_frames=0 failed=""
  for n in $buses_list; do
    if throughput_step "$d/n$n" "$n"; then
      [ -n "$failed" ] || { best=$n; best_cpu=$(get "$d/n$n/step" bridge_cpu_pct); }
      echo "throughput: $n bus(es) x $devices saws at $full_rate frames/s: no loss, bridge CPU $(get "$d/n$n/step" bridge_cpu_pct) %" >&2
    else
      echo "throughput: $n bus(es): loss, $(get "$d/n$n/step" samples) of $(get "$d/n$n/step" sent) samples, bridge took $(get "$d/n$n/step" bridge_frames_in) frames, bridge CPU $(get "$d/n$n/step" bridge_cpu_pct) % (details: $d/n$n/step)" >&2
      if [ -z "$failed" ]; then
        failed=$n
        echo "throughput_first_fail=$n" >>"$vals"
        echo "throughput_fail_cpu_pct=$(get "$d/n$n/step" bridge_cpu_pct)" >>"$vals"
        echo "throughput_fail_inject_cpu_pct=$(get "$d/n$n/step" inject_cpu_pct)" >>"$vals"
        echo "throughput_fail_sub_cpu_pct=$(get "$d/n$n/step" sub_cpu_pct)" >>"$vals"
      fi
    fi
    echo "throughput_cpu_pct_n$n=$(get "$d/n$n/step" bridge_cpu_pct)" >>"$vals"
    echo "throughput_superseded_n$n=$(get "$d/n$n/step" channel_superseded)" >>"$vals"
    echo "throughput_samples_per_s_per_bus_n$n=$(get "$d/n$n/step" samples_per_s_per_bus)" >>"$vals"
    echo "throughput_last_p50_us_n$n=$(get "$d/n$n/step" loaded_last_p50_us)" >>"$vals"
    echo "throughput_frames_per_sample_n$n=$(awk -v f="$(get "$d/n$n/step" samples)" -v s="$(get "$d/n$n/step" samples_published)" 'BEGIN { if (s > 0) printf "%.2f", f / s }')" >>"$vals"
    [ "$(get "$d/n$n/step" frames_ok)" = 1 ] || break
    best_frames=$n
  done
  echo "throughput_max_buses=$best" >>"$vals"
  echo "throughput_max_buses_frames=$best_frames" >>"$vals"
  [ -z "$best_cpu" ] || echo "throughput_cpu_pct=$best_cpu" >>"$vals"
  per_bus=$(get "$d/n1/step" bridge_cpu_pct)
  [ -z "$per_bus" ] || echo "throughput_cpu_pct_1bus=$per_bus" >>"$vals"
}

# The bridge's CPU at full load, not scraped and scraped every second, alternating in chunks; per
# N the mean over the chunks (each chunk a throughput step of its own: a fresh bridge and load).
fig_scrape() {  # RUN
  local d="$out_dir/scrape/run$1" n c what
  vals="$d/values"; mkdir -p "$d"; : >"$vals"
  for n in $scrape_buses; do
    for ((c = 1; c <= chunks; c++)); do
      throughput_step "$d/n$n/plain/c$c" "$n" || echo "bench.sh: scrape: $n bus(es), not scraped, chunk $c: loss (see $d/n$n/plain/c$c/step)" >&2
      throughput_step "$d/n$n/scraped/c$c" "$n" scrape || echo "bench.sh: scrape: $n bus(es), scraped, chunk $c: loss (see $d/n$n/scraped/c$c/step)" >&2
    done
    for what in plain scraped; do
      cat "$d/n$n/$what"/c*/step | awk -F= -v k="scrape_${what}_n$n" '
        $1 == "bridge_cpu_pct" { cpu += $2; steps++ }
        $1 == "sent" { sent += $2 } $1 == "samples" { got += $2 }
        $1 == "scrapes" { scrapes += $2 } $1 == "scrapes_ok" { ok += $2 }
        $1 == "scrape_kib" && $2 != "" { kib += $2; kn++ } $1 == "scrape_ms" && $2 != "" { ms += $2; mn++ }
        $1 == "scrape_cpu_ms" && $2 != "" { cms += $2; cn++ }
        END {
          if (steps) printf "%s_cpu_pct=%.1f\n", k, cpu / steps
          printf "%s_missing=%d\n", k, sent - got
          if (scrapes) printf "%s_scrapes=%d\n%s_scrapes_ok=%d\n", k, scrapes, k, ok
          if (kn) printf "%s_kib=%.0f\n", k, kib / kn
          if (mn) printf "%s_ms=%.1f\n", k, ms / mn
          if (cn) printf "%s_cpu_ms_per_scrape=%.2f\n%s_cpu_pct_at_1s=%.2f\n", k, cms / cn, k, cms / cn / 10
        }' >>"$vals"
    done
    awk -F= -v n="$n" '$1 == "scrape_plain_n" n "_cpu_pct" { a = $2 } $1 == "scrape_scraped_n" n "_cpu_pct" { b = $2 }
      END { if (a != "" && b != "") printf "scrape_cost_n%s_cpu_pct=%.1f\n", n, b - a }' "$vals" >>"$vals"
    echo "scrape: $n bus(es): bridge CPU $(get "$vals" scrape_plain_n${n}_cpu_pct) % not scraped, $(get "$vals" scrape_scraped_n${n}_cpu_pct) % scraped every second" >&2
  done
}

fig_memory() {  # RUN: reuses the throughput run's 8-bus step when there is one
  local d="$out_dir/memory/run$1" step="$out_dir/throughput/run$1/n$mem_buses/step"
  mkdir -p "$d"
  vals="$d/values"; : >"$vals"
  if [ ! -f "$step" ]; then
    throughput_step "$d/n$mem_buses" $mem_buses || true
    step="$d/n$mem_buses/step"
  fi
  echo "memory_rss_mib=$(mib "$(get "$step" rss_kib)")" >>"$vals"
  echo "memory_hwm_mib=$(mib "$(get "$step" hwm_kib)")" >>"$vals"
  echo "memory_pss_mib=$(mib "$(get "$step" pss_kib)")" >>"$vals"
}

fig_startup() {  # RUN: each size several times (discovery makes the spread worth seeing)
  local d="$out_dir/startup/run$1"
  mkdir -p "$d"
  vals="$d/values"; : >"$vals"
  local spec b n k reps i=0
  for spec in 1x1 ${mem_buses}x$devices; do
    b=${spec%x*}; n=${spec#*x}
    i=$((i + 1))
    reps=$(echo $startup_reps | cut -d' ' -f$i)
    for ((k = 1; k <= reps; k++)); do
      next_domain
      local base="$d/$spec-$k"
      "$bin/bench-config" --buses "$b" --devices "$n" --domain $domain --prefix "st-$spec-$1-$k" --role master >"$base.yaml"
      # The simulator plays the saws (and hosts the buses) before the bridge starts, as on a line
      # whose devices are powered: the first samples announce the devices, the first online ones
      # carry their live data after the bridge booted them.
      start "$base.sim" "$sim_bin" --config "$base.yaml"
      local sim=$pid
      sleep 1
      printf '%s\n' "$bin/bench-startup --online --buses $b --devices $n --domain $domain --log $base.bridge.log --watch-pid SIMULATOR -- $bridge_bin --config $base.yaml" >>"$commands"
      "$bin/bench-startup" --online --buses "$b" --devices "$n" --domain $domain --log "$base.bridge.log" \
        --watch-pid $sim -- "$bridge_bin" --config "$base.yaml" >"$base.out" 2>"$base.err" || true
      stop $sim
      echo "startup_${spec}_first_ms=$(get "$base.out" startup_first_ms)" >>"$vals"
      echo "startup_${spec}_all_ms=$(get "$base.out" startup_all_ms)" >>"$vals"
      echo "startup_${spec}_first_online_ms=$(get "$base.out" startup_first_online_ms)" >>"$vals"
      echo "startup_${spec}_all_online_ms=$(get "$base.out" startup_all_online_ms)" >>"$vals"
      for q in 10 50 90; do echo "startup_${spec}_online_p${q}_ms=$(get "$base.out" startup_online_p${q}_ms)" >>"$vals"; done
      echo "startup_${spec}_rss_mib=$(mib "$(get "$base.out" startup_rss_kib)")" >>"$vals"
      echo "startup_${spec}_pss_mib=$(mib "$(get "$base.out" startup_pss_kib)")" >>"$vals"
      for part in window bus dds watched sub; do echo "startup_${spec}_cpu_${part}_ms=$(get "$base.out" startup_cpu_${part}_ms)" >>"$vals"; done
      for f in found_dds found_first_status_writer found_all_status_writers; do echo "startup_${spec}_${f}_ms=$(get "$base.out" startup_${f}_ms)" >>"$vals"; done
    done
  done
}

# startup_1x1 DIR: one start of the bridge (1 saw, the simulator already playing it) -> its first
# status sample, and its first sample with the saw online, at a running subscriber.
startup_1x1() {
  local d=$1 sim
  mkdir -p "$d"
  next_domain
  secured observer
  "$bin/bench-config" --buses 1 --devices 1 --domain $domain --prefix "stsec-$RANDOM" --role master "${sec_cfg[@]}" >"$d/line.yaml"
  start "$d/sim" "$sim_bin" --config "$d/line.yaml"
  sim=$pid
  sleep 1
  printf '%s\n' "$bin/bench-startup --online --buses 1 --devices 1 --domain $domain ${sec[*]} --log $d/bridge.log -- $bridge_bin --config $d/line.yaml" >>"$commands"
  "$bin/bench-startup" --online --buses 1 --devices 1 --domain $domain "${sec[@]}" --log "$d/bridge.log" -- \
    "$bridge_bin" --config "$d/line.yaml" >"$d/out" 2>"$d/err" || true
  stop $sim
}

# A PKI for the secured steps (pki.sh, as an integrator makes one): the bridge, an observer, an
# engineer (set values of every device).
security_pki() {  # DIR
  local d=$1
  "$bin/bench-config" --buses 1 --devices 1 --domain $secure_domain --prefix pki >"$d.line.yaml"
  LINEBRIDGE_BIN="$build_dir/bridge/app" "$root/launch_scripts/pki.sh" init --config "$d.line.yaml" --dir "$d" >/dev/null
  LINEBRIDGE_BIN="$build_dir/bridge/app" "$root/launch_scripts/pki.sh" issue --config "$d.line.yaml" --dir "$d" --name observer --role observer 2>/dev/null
  LINEBRIDGE_BIN="$build_dir/bridge/app" "$root/launch_scripts/pki.sh" issue --config "$d.line.yaml" --dir "$d" --name engineer --role engineer 2>/dev/null
}

# jitter_step DIR SCENARIO: idle | quiet | frozen | record. A master bridge (pinned) with 30 saws
# whose TPDOs come at full load from the injector, an EMCY burst from the meter, and the
# scenario's burden (idle: no TPDOs, no EMCYs); the meter reports the SYNC periods it saw.
jitter_step() {
  local d=$1 scenario=$2 inj="" bridge meter reader="" drain="" prefix="jit-$scenario-$RANDOM" extra=()
  local rate=${jitter_rate:-$full_rate} emcy=1000
  [ "$scenario" != idle ] || { rate=0; emcy=0; }
  mkdir -p "$d"
  next_domain
  if [ "$scenario" = record ]; then
    # A "slow disk": a FIFO whose reader takes 16 KiB a second; a frame's line is ~40 bytes, so
    # the bridge's recording (8000+ frames/s) is ~20 times faster than the disk.
    mkfifo "$d/record.fifo"
    start "$d/drain" python3 -c "import sys,time
f=open(sys.argv[1],'rb',buffering=0)
while f.read(1024): time.sleep(1/16)" "$d/record.fifo"
    drain=$pid
    extra=(--record "$d/record.fifo")
  fi
  "$bin/bench-config" --buses 1 --devices $devices --domain $domain --prefix "$prefix" --role master \
    --realtime-priority $rt_priority "${extra[@]}" >"$d/line.yaml"
  if ((rate > 0)); then
    start "$d/inject" "${harness_cmd[@]}" "$bin/bench-inject" --buses 1 --devices $devices --rate $rate \
      --count $((rate * (jitter_s + 8))) --prefix "$prefix" --ready "$d/inject.ready" --go "$d/go" --linger 1
    inj=$pid
    wait_file "$d/inject.ready" $inj
  fi
  start "$d/bridge" "${pin_cmd[@]}" "$bridge_bin" --config "$d/line.yaml" --log-level warn
  bridge=$pid
  if [ "$scenario" = frozen ]; then
    start "$d/reader" "${harness_cmd[@]}" "$bin/bench-frozen-reader" --devices $devices --domain $domain --freeze-after 4
    reader=$pid
  fi
  sleep 3
  touch "$d/go"
  sleep 2
  "${harness_cmd[@]}" "$bin/bench-sync-jitter" --bus "virtual:$prefix-0" --duration $jitter_s \
    --emcy-rate $emcy --emcy-devices $devices --out "$d/periods" "${sentinel_args[@]}" >"$d/meter.out" 2>"$d/meter.err" || true
  printf '%s\n' "$bin/bench-sync-jitter --bus virtual:$prefix-0 --duration $jitter_s --emcy-rate $emcy --emcy-devices $devices --out $d/periods ${sentinel_args[*]}" >>"$commands"
  # SIGKILL: a stopped process does not act on SIGTERM. The wait's report goes to the reader's log.
  [ -z "$reader" ] || { kill -KILL "$reader" 2>/dev/null || true; finish "$reader" 2>>"$d/reader.err" || true; }
  echo "bridge_alive=$(kill -0 $bridge 2>/dev/null && echo 1 || echo 0)" >>"$d/meter.out"
  stop $bridge
  [ -z "$inj" ] || stop $inj
  [ -z "$drain" ] || stop "$drain"
}

fig_jitter() {  # RUN
  local d="$out_dir/jitter/run$1" scenario awake=""
  mkdir -p "$d"
  vals="$d/values"; : >"$vals"
  if ((keep_awake)); then
    start "$d/awake" "${pin_cmd[@]}" chrt -i 0 sh -c 'while :; do :; done'
    awake=$pid
  fi
  # The floor: how late this machine wakes a bare periodic timer on the bridge's core.
  echo "jitter: timer floor" >&2
  local floor_cmd=("${pin_cmd[@]}")
  ((rt_priority == 0)) || floor_cmd+=(chrt -f $rt_priority)
  "${floor_cmd[@]}" "$bin/bench-timer-floor" --duration $jitter_s "${sentinel_args[@]}" >"$d/floor.out"
  printf '%s\n' "${floor_cmd[*]} $bin/bench-timer-floor --duration $jitter_s ${sentinel_args[*]}" >>"$commands"
  for k in wakeups p50_us p99_us p999_us max_us host_stalls clean_p50_us clean_p99_us clean_p999_us clean_max_us; do
    echo "jitter_floor_$k=$(get "$d/floor.out" floor_$k)" >>"$vals"
  done
  echo "jitter_floor_clean_wakeups=$(get "$d/floor.out" floor_clean_n)" >>"$vals"
  for scenario in idle quiet frozen record; do
    echo "jitter: $scenario" >&2
    jitter_step "$d/$scenario" $scenario
    for k in syncs expected_syncs p50_us p99_us p999_us max_us longest_period_us emcy_sent read_p50_us read_p99_us read_p999_us read_max_us \
      host_stalls host_stalled_ms host_longest_stall_us clean_p50_us clean_p99_us clean_p999_us clean_max_us; do
      echo "jitter_${scenario}_$k=$(get "$d/$scenario/meter.out" jitter_$k)" >>"$vals"
    done
    echo "jitter_${scenario}_clean_periods=$(get "$d/$scenario/meter.out" jitter_clean_n)" >>"$vals"
    echo "jitter_${scenario}_bridge_alive=$(get "$d/$scenario/meter.out" bridge_alive)" >>"$vals"
  done
  # p99.9 over a baseline, over all periods and between host stalls: each loaded scenario over the
  # idle bus (the unloaded figure), and the burdens over the same load alone.
  local base kind
  for base in "idle:quiet frozen record" "quiet:frozen record"; do
    for kind in "" clean_; do
      for scenario in ${base#*:}; do
        echo "jitter_${scenario}_${kind}p999_over_${base%%:*}_us=$(awk -v a="$(get "$vals" jitter_${scenario}_${kind}p999_us)" \
          -v b="$(get "$vals" jitter_${base%%:*}_${kind}p999_us)" 'BEGIN { if (a != "" && b != "") printf "%.1f", a - b }')" >>"$vals"
      done
    done
  done
  [ -z "$awake" ] || stop $awake
}

# A flood for the soak: full load from the injector, an EMCY burst, and frames on every 11-bit
# identifier with random lengths and data (hostile and malformed as they come).
fig_soak() {  # RUN
  local d="$out_dir/soak/run$1" inj bridge prefix="soak-$1-$RANDOM" t=0
  mkdir -p "$d"
  vals="$d/values"; : >"$vals"
  next_domain
  # other_master: warn: the hostile frames include SYNC, NMT and the saws' RPDO identifiers, which
  # would make a yielding bridge fall silent; the soak wants it mastering the bus all along.
  "$bin/bench-config" --buses 1 --devices $devices --domain $domain --prefix "$prefix" --role master \
    --other-master warn --realtime-priority $rt_priority >"$d/line.yaml"
  start "$d/inject" "${harness_cmd[@]}" "$bin/bench-inject" --buses 1 --devices $devices --rate $full_rate \
    --count $((full_rate * (soak_s + 20))) --prefix "$prefix" --ready "$d/inject.ready" --go "$d/go" --linger 1
  inj=$pid
  wait_file "$d/inject.ready" $inj
  start "$d/bridge" "${pin_cmd[@]}" "$bridge_bin" --config "$d/line.yaml" --log-level warn
  bridge=$pid
  sleep 3
  touch "$d/go"
  start "$d/hostile" "${harness_cmd[@]}" "$bin/bench-sync-jitter" --bus "virtual:$prefix-0" --duration $((soak_s + 5)) \
    --emcy-rate 1000 --emcy-devices $devices --hostile-rate 1000
  local hostile=$pid
  start "$d/flood" "${harness_cmd[@]}" "$bin/bench-request-flood" --devices $devices --domain $domain \
    --clients 3 --writers 2 --duration $soak_s
  local flood=$pid
  : >"$d/samples"
  while ((t <= soak_s)); do
    echo "t=$t rss_kib=$(mem_kib $bridge VmRSS) fds=$(ls /proc/$bridge/fd 2>/dev/null | wc -l)" >>"$d/samples"
    sleep 10
    t=$((t + 10))
  done
  finish $flood || echo "bench.sh: the request flood failed (see $d/flood.err)" >&2
  echo "soak_bridge_alive=$(kill -0 $bridge 2>/dev/null && echo 1 || echo 0)" >>"$vals"
  finish $hostile || echo "bench.sh: the SYNC meter failed (see $d/hostile.err)" >&2
  for k in flood_requests_sent flood_requests_answered flood_requests_refused flood_requests_unanswered \
    flood_requests_per_s flood_setpoints_written flood_setpoints_per_s flood_bridge_requests_refused \
    flood_bridge_commands_lost; do
    echo "soak_$k=$(get "$d/flood.out" $k)" >>"$vals"
  done
  for k in syncs expected_syncs p50_us p99_us p999_us max_us; do
    echo "soak_sync_$k=$(get "$d/hostile.out" jitter_$k)" >>"$vals"
  done
  stop $bridge
  stop $inj
  awk '{ split($2, r, "="); split($3, f, "=");
         if (NR == 1) { r0 = r[2]; f0 = f[2] } r1 = r[2]; f1 = f[2];
         if (r[2] > rmax) rmax = r[2]; if (f[2] > fmax) fmax = f[2] }
       END { printf "soak_rss_start_mib=%.1f\nsoak_rss_end_mib=%.1f\nsoak_rss_max_mib=%.1f\nsoak_fds_start=%d\nsoak_fds_end=%d\nsoak_fds_max=%d\nsoak_samples=%d\n",
             r0 / 1024, r1 / 1024, rmax / 1024, f0, f1, fmax, NR }' "$d/samples" >>"$vals"
}

fig_security() {  # RUN
  local d="$out_dir/security/run$1" c mode
  vals="$d/values"; mkdir -p "$d"; : >"$vals"
  security_pki "$d/pki"
  for ((c = 1; c <= chunks; c++)); do
    for mode in plain secured; do
      secure_pki=""
      [ "$mode" = plain ] || secure_pki="$d/pki"
      mkdir -p "$d/$mode/dds/c$c" "$d/$mode/bridge/c$c" "$d/$mode/setpoint/c$c"
      dds_floor "$d/$mode/dds/c$c"
      vals="$d/$mode.chunks"  # the per-chunk lines of the two paths, per mode
      path_can2dds "$d/$mode/bridge/c$c" "sec-$mode-$1-$c" bridge
      setpoint_bridge "$d/$mode/setpoint/c$c" "sec-sp-$mode-$1-$c"
      vals="$d/values"
      startup_1x1 "$d/$mode/startup/c$c"
    done
  done
  secure_pki=""
  for mode in plain secured; do
    sed -n 's/^chunk_bridge_cpu_pct=//p' "$d/$mode.chunks" |
      awk -v k="security_${mode}_bridge_cpu_pct" '{ s += $1 } END { if (NR) printf "%s=%.1f\n", k, s / NR }' >>"$vals"
    sed -n 's/^chunk_\(bridge_missing\|lost\)=//p' "$d/$mode.chunks" |
      awk -v k="security_${mode}_missing" '{ s += $1 } END { if (NR) printf "%s=%d\n", k, s }' >>"$vals"
  done
  for mode in plain secured; do
    cat "$d/$mode"/dds/c*/dds.lat >"$d/$mode.dds.lat"
    cat "$d/$mode"/bridge/c*/bridge.lat >"$d/$mode.can2dds.lat"
    cat "$d/$mode"/setpoint/c*/bridge.lat >"$d/$mode.dds2can.lat"
    "$bin/bench-stats" summary "$d/$mode.dds.lat" | sed "s/^lat_/security_${mode}_dds_/" >>"$vals"
    "$bin/bench-stats" summary "$d/$mode.can2dds.lat" | sed "s/^lat_/security_${mode}_can2dds_/" >>"$vals"
    "$bin/bench-stats" summary "$d/$mode.dds2can.lat" | sed "s/^lat_/security_${mode}_dds2can_/" >>"$vals"
    for c in "$d/$mode"/startup/c*; do
      echo "security_${mode}_startup_first_ms=$(get "$c/out" startup_first_ms)" >>"$vals"
      echo "security_${mode}_startup_online_ms=$(get "$c/out" startup_all_online_ms)" >>"$vals"
    done
  done
}

# The channel between the bus and the DDS process by itself: the real link::BusChannel and
# link::DdsChannel in two processes, one sample in flight; the same through iceoryx when built.
# Both processes on the bridge's core (as the split bridge runs in these benchmarks), then spread
# over every core.
fig_hop() {  # RUN
  local d="$out_dir/hop/run$1" n=20000 where roudi
  ((!quick)) || n=5000
  mkdir -p "$d"
  vals="$d/values"; : >"$vals"
  for where in core spread; do
    local cpu=()
    [ $where = spread ] || cpu=("${pin_cmd[@]}")
    printf '%s\n' "${cpu[*]} $bin/bench-channel-hop --count $n --dir $d" >>"$commands"
    "${cpu[@]}" "$bin/bench-channel-hop" --count $n --dir "$d" >"$d/unix-$where.out" 2>"$d/unix-$where.err" || true
    sed -n "s/^hop_\([a-z0-9_]*\)=\([0-9.]*\)$/hop_unix_${where}_\1=\2/p" "$d/unix-$where.out" >>"$vals"
    if [ -x "$bin/bench-iceoryx-hop" ] && command -v iox-roudi >/dev/null; then
      start "$d/roudi-$where" iox-roudi
      roudi=$pid
      sleep 1
      printf '%s\n' "${cpu[*]} $bin/bench-iceoryx-hop --count $n" >>"$commands"
      "${cpu[@]}" "$bin/bench-iceoryx-hop" --count $n >"$d/iceoryx-$where.out" 2>"$d/iceoryx-$where.err" || true
      stop $roudi
      sed -n "s/^hop_\([a-z0-9_]*\)=\([0-9.]*\)$/hop_iceoryx_${where}_\1=\2/p" "$d/iceoryx-$where.out" >>"$vals"
    fi
  done
}

# hopjitter_step DIR SCENARIO bridge|single: a secured master line (30 saws at full load, an EMCY
# burst), the split bridge or --part single pinned to its core, and the DDS side's burden: quiet
# (none), observers (20 observer participants on every status topic), flood (forged discovery
# announcements, 3,000 at 2,000/s, again and again while the meter runs). The meter reports the
# SYNC periods; the bridge's CPU (both processes) and its bus process's alone.
hopjitter_step() {
  local d=$1 scenario=$2 what=$3 inj bridge meter obs="" flood="" prefix="hj-$scenario-$3-$RANDOM"
  local rate=${jitter_rate:-$full_rate}
  mkdir -p "$d"
  next_domain
  secured observer
  "$bin/bench-config" --buses 1 --devices $devices --domain $domain --prefix "$prefix" --role master \
    --realtime-priority $rt_priority "${sec_cfg[@]}" >"$d/line.yaml"
  start "$d/inject" "${harness_cmd[@]}" "$bin/bench-inject" --buses 1 --devices $devices --rate $rate \
    --count $((rate * (jitter_s + 120))) --prefix "$prefix" --ready "$d/inject.ready" --go "$d/go" --linger 1
  inj=$pid
  wait_file "$d/inject.ready" $inj
  start "$d/bridge" "${pin_cmd[@]}" "$bridge_bin" --config "$d/line.yaml" --log-level warn $(bridge_part "$what")
  bridge=$pid
  sleep 3
  if [ "$scenario" = observers ]; then
    start "$d/observers" "${harness_cmd[@]}" "$bin/bench-observers" --participants 20 --devices $devices --domain $domain \
      --ready "$d/observers.ready" "${sec[@]}"
    obs=$pid
    wait_file "$d/observers.ready" $obs 180 || true
  fi
  touch "$d/go"
  sleep 2
  local dds0 c0 b0 t0 c1 b1 t1
  dds0=$(children $bridge | tr '\n' ' ')
  c0=$(tree_ticks $bridge); b0=$(cpu_ticks $bridge); t0=$(now_ns)
  if [ "$scenario" = flood ]; then
    start "$d/flood" "${harness_cmd[@]}" bash -c 'end=$((SECONDS + $1)); shift; n=0
      while ((SECONDS < end)); do "$@" || echo "flood_tool_failed=1"; n=$((n + 1)); done; echo "flood_rounds=$n"' \
      flood $jitter_s "$bin/bench-forged-announcements" --domain $domain --pki "$secure_pki" --identity observer --count 3000 --rate 2000
    flood=$pid
  fi
  "${harness_cmd[@]}" "$bin/bench-sync-jitter" --bus "virtual:$prefix-0" --duration $jitter_s \
    --emcy-rate 1000 --emcy-devices $devices --out "$d/periods" "${sentinel_args[@]}" >"$d/meter.out" 2>"$d/meter.err" || true
  printf '%s\n' "$bin/bench-sync-jitter --bus virtual:$prefix-0 --duration $jitter_s --emcy-rate 1000 --emcy-devices $devices --out $d/periods ${sentinel_args[*]}" >>"$commands"
  c1=$(tree_ticks $bridge); b1=$(cpu_ticks $bridge); t1=$(now_ns)
  {
    echo "bridge_alive=$(kill -0 $bridge 2>/dev/null && echo 1 || echo 0)"
    echo "cpu_pct=$(cpu_percent "$c0" "$c1" "$t0" "$t1")"
    echo "bus_cpu_pct=$(cpu_percent "$b0" "$b1" "$t0" "$t1")"
    echo "dds_pids_before=$dds0"
    echo "dds_pids_after=$(children $bridge | tr '\n' ' ')"
  } >>"$d/meter.out"
  [ -z "$flood" ] || finish $flood || true
  [ -z "$obs" ] || stop $obs
  stop $bridge
  stop $inj
}

fig_hopjitter() {  # RUN
  local d="$out_dir/hopjitter/run$1" scenario what k
  mkdir -p "$d"
  vals="$d/values"; : >"$vals"
  security_pki "$d/pki"
  secure_pki="$d/pki"
  for scenario in quiet observers flood; do
    for what in bridge single; do
      echo "hopjitter: $scenario, $what" >&2
      hopjitter_step "$d/$scenario-$what" $scenario $what
      for k in syncs expected_syncs p50_us p99_us p999_us max_us longest_period_us host_stalls clean_p50_us clean_p99_us clean_p999_us clean_max_us; do
        echo "hopjitter_${scenario}_${what}_$k=$(get "$d/$scenario-$what/meter.out" jitter_$k)" >>"$vals"
      done
      for k in bridge_alive cpu_pct bus_cpu_pct; do
        echo "hopjitter_${scenario}_${what}_$k=$(get "$d/$scenario-$what/meter.out" $k)" >>"$vals"
      done
      # The DDS process replaced during the step (its PID changed): the supervisor restarted it.
      [ "$what" = single ] || echo "hopjitter_${scenario}_${what}_dds_replaced=$([ "$(get "$d/$scenario-$what/meter.out" dds_pids_before)" = "$(get "$d/$scenario-$what/meter.out" dds_pids_after)" ] && echo 0 || echo 1)" >>"$vals"
    done
  done
  secure_pki=""
}

# ------------------------------------------------------------------------------------------------
want() { [[ ",$only," == *",$1,"* ]]; }
begin=$(date +%s)
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
if ((report_only)); then
  runs=$(find "$out_dir" -mindepth 2 -maxdepth 2 -type d -name 'run*' | sed 's/.*run//' | sort -n | tail -1)
  [ -n "$runs" ] || { echo "bench.sh: no measurements in $out_dir" >&2; exit 1; }
  # The transport the figures were measured with, not this invocation's (--shared-memory).
  if [ "$(cat "$out_dir/transport" 2>/dev/null)" = shared-memory ]; then export LINEBRIDGE_BENCH_SHARED_MEMORY=1; else unset LINEBRIDGE_BENCH_SHARED_MEMORY; fi
else
  if [ -n "${LINEBRIDGE_BENCH_SHARED_MEMORY:-}" ]; then echo shared-memory; else echo udp; fi >"$out_dir/transport"
  for ((r = 1; r <= runs; r++)); do
    for f in can2dds dds2can throughput memory startup security jitter soak hop hopjitter scrape; do
      if want $f; then
        echo "== $f, run $r of $runs" >&2
        "fig_$f" $r
      fi
    done
  done
fi

# ------------------------------------------------------------------------------------------------
# The table: median over the runs, and the range when there is more than one.
# stat FIGURE KEY -> "median" or "median (min-max)"; empty when never measured.
stat() {
  cat "$out_dir/$1"/run*/values 2>/dev/null | sed -n "s/^$2=//p" | grep -v '^$' | sort -g |
    awk -v runs="$runs" '{ v[NR] = $1 } END {
      if (NR == 0) exit
      m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
      if (NR > 1) printf "%g (%g-%g)", m, v[1], v[NR]; else printf "%g", m }' || true
}
median() { stat "$1" "$2" | awk '{ print $1 }'; }
verdict() {  # VALUE OP LIMIT
  [ -n "$1" ] || { echo "n/a"; return; }
  awk -v v="$1" -v l="$3" -v op="$2" 'BEGIN { ok = (op == "<=") ? v <= l : v >= l; print ok ? "PASS" : "FAIL" }'
}

table="$out_dir/table.md"
run_flags=""
[ "$niceness" = 0 ] || run_flags=" --nice $niceness"
((rt_priority == 0)) || run_flags+=" --realtime-priority $rt_priority"
((!keep_awake)) || run_flags+=" --keep-awake"
[ -z "${LINEBRIDGE_BENCH_SHARED_MEMORY:-}" ] || run_flags+=" --shared-memory"
((pin)) || run_flags+=" --no-pin"
[ "$scrape_buses" = "1 $mem_buses" ] || ! want scrape || run_flags+=" --scrape-buses '$scrape_buses'"
cmd() { echo "launch_scripts/bench.sh --only $1$quick_flag --runs $runs$run_flags"; }
{
  echo "| figure | value | target | result | reproduce |"
  echo "| --- | --- | --- | --- | --- |"
  if want can2dds; then
    echo "| CAN->DDS latency, bridge p50 / p99 / p99.9 / max (µs) | $(stat can2dds can2dds_bridge_p50_us) / $(stat can2dds can2dds_bridge_p99_us) / $(stat can2dds can2dds_bridge_p999_us) / $(stat can2dds can2dds_bridge_max_us) | | | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS floor: bus hop + DDS hop p50 / p99 / p99.9 (µs) | $(stat can2dds can2dds_floor_p50_us) / $(stat can2dds can2dds_floor_p99_us) / $(stat can2dds can2dds_floor_p999_us) | | | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS bare bus hop p50 / p99 (µs); bare DDS hop p50 / p99 (µs) | $(stat can2dds can2dds_bus_p50_us) / $(stat can2dds can2dds_bus_p99_us); $(stat can2dds can2dds_dds_p50_us) / $(stat can2dds can2dds_dds_p99_us) | | | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS overhead over the floor, p50 (µs) | $(stat can2dds can2dds_overhead_p50_us) | <= 20 | $(verdict "$(median can2dds can2dds_overhead_p50_us)" "<=" 20) | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS overhead over the floor, p99 (µs) | $(stat can2dds can2dds_overhead_p99_us) | <= 100 | $(verdict "$(median can2dds can2dds_overhead_p99_us)" "<=" 100) | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS samples (n per set), missing | $(stat can2dds can2dds_bridge_n), $(stat can2dds can2dds_bridge_missing) | 0 missing | $(verdict "$(median can2dds can2dds_bridge_missing)" "<=" 0) | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS bare relay (same 3-process path, no bridge logic) p50 / p99 / p99.9 (µs) | $(stat can2dds can2dds_relay_p50_us) / $(stat can2dds can2dds_relay_p99_us) / $(stat can2dds can2dds_relay_p999_us) | | | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS bridge minus bare relay p50 / p99 (µs) | $(stat can2dds can2dds_over_relay_p50_us) / $(stat can2dds can2dds_over_relay_p99_us) | | | \`$(cmd can2dds)\` |"
    echo "| CAN->DDS the method's own noise: bare relay minus bare relay (its odd chunks minus its even ones) p50 / p99 (µs) | $(stat can2dds can2dds_relay_self_p50_us) / $(stat can2dds can2dds_relay_self_p99_us) | | | \`$(cmd can2dds)\` |"
    echo "| CPU at $lat_rate frames/s, 1 bus x $devices saws (% of a core): bridge (split: both processes); bare relay | $(stat can2dds can2dds_bridge_cpu_pct); $(stat can2dds can2dds_relay_cpu_pct) | | | \`$(cmd can2dds)\` |"
    if ((single)); then
      echo "| CAN->DDS one-process bridge (--part single), same run, p50 / p99 / p99.9 (µs); CPU (% of a core); missing | $(stat can2dds can2dds_single_p50_us) / $(stat can2dds can2dds_single_p99_us) / $(stat can2dds can2dds_single_p999_us); $(stat can2dds can2dds_single_cpu_pct); $(stat can2dds can2dds_single_missing) | | | \`$(cmd can2dds)\` |"
      echo "| CAN->DDS the hop's cost: split minus single, p50 (µs) | $(stat can2dds can2dds_split_over_single_p50_us) | <= 20 | $(verdict "$(median can2dds can2dds_split_over_single_p50_us)" "<=" 20) | \`$(cmd can2dds)\` |"
      echo "| CAN->DDS split minus single, p99 / p99.9 (µs) | $(stat can2dds can2dds_split_over_single_p99_us) / $(stat can2dds can2dds_split_over_single_p999_us) | | | \`$(cmd can2dds)\` |"
    fi
  fi
  if want dds2can; then
    echo "| DDS->CAN latency, bridge p50 / p99 / p99.9 / max (µs) | $(stat dds2can dds2can_bridge_p50_us) / $(stat dds2can dds2can_bridge_p99_us) / $(stat dds2can dds2can_bridge_p999_us) / $(stat dds2can dds2can_bridge_max_us) | | | \`$(cmd dds2can)\` |"
    echo "| DDS->CAN floor: bare relay p50 / p99 / p99.9 (µs) | $(stat dds2can dds2can_floor_p50_us) / $(stat dds2can dds2can_floor_p99_us) / $(stat dds2can dds2can_floor_p999_us) | | | \`$(cmd dds2can)\` |"
    echo "| DDS->CAN relay + the bridge's BusLoop hand-over p50 / p99 / p99.9 (µs) | $(stat dds2can dds2can_handoff_p50_us) / $(stat dds2can dds2can_handoff_p99_us) / $(stat dds2can dds2can_handoff_p999_us) | | | \`$(cmd dds2can)\` |"
    echo "| DDS->CAN overhead over the floor, p50 (µs) | $(stat dds2can dds2can_overhead_p50_us) | <= 20 | $(verdict "$(median dds2can dds2can_overhead_p50_us)" "<=" 20) | \`$(cmd dds2can)\` |"
    echo "| DDS->CAN overhead over the floor, p99 (µs) | $(stat dds2can dds2can_overhead_p99_us) | <= 100 | $(verdict "$(median dds2can dds2can_overhead_p99_us)" "<=" 100) | \`$(cmd dds2can)\` |"
    echo "| DDS->CAN the method's own noise: floor minus floor (its odd chunks minus its even ones) p50 / p99 (µs) | $(stat dds2can dds2can_floor_self_p50_us) / $(stat dds2can dds2can_floor_self_p99_us) | | | \`$(cmd dds2can)\` |"
    echo "| DDS->CAN set values (n per set), lost | $(stat dds2can dds2can_bridge_n), $(stat dds2can dds2can_lost) | 0 lost | $(verdict "$(median dds2can dds2can_lost)" "<=" 0) | \`$(cmd dds2can)\` |"
    if ((single)); then
      echo "| DDS->CAN one-process bridge (--part single), same run, p50 / p99 / p99.9 (µs); lost | $(stat dds2can dds2can_single_p50_us) / $(stat dds2can dds2can_single_p99_us) / $(stat dds2can dds2can_single_p999_us); $(stat dds2can dds2can_single_lost) | | | \`$(cmd dds2can)\` |"
      echo "| DDS->CAN the hop's cost: split minus single, p50 (µs) | $(stat dds2can dds2can_split_over_single_p50_us) | <= 20 | $(verdict "$(median dds2can dds2can_split_over_single_p50_us)" "<=" 20) | \`$(cmd dds2can)\` |"
      echo "| DDS->CAN split minus single, p99 / p99.9 (µs) | $(stat dds2can dds2can_split_over_single_p99_us) / $(stat dds2can dds2can_split_over_single_p999_us) | | | \`$(cmd dds2can)\` |"
    fi
    echo "| DDS->CAN this machine's hand-overs where the bridge runs (its core when pinned; bench-switch: a byte over pipes, one way): to a thread p50 / p99; to a process p50 / p99 (µs) | $(stat dds2can dds2can_switch_thread_oneway_p50_us) / $(stat dds2can dds2can_switch_thread_oneway_p99_us); $(stat dds2can dds2can_switch_process_oneway_p50_us) / $(stat dds2can dds2can_switch_process_oneway_p99_us) | | | \`$(cmd dds2can)\` |"
  fi
  if want throughput; then
    echo "| Buses x $devices saws at $full_rate frames/s, no frame lost, no sample missing (bridge pinned to 1 core) | $(stat throughput throughput_max_buses) (tried: $buses_list) | >= 8 | $(verdict "$(median throughput throughput_max_buses)" ">=" 8) | \`$(cmd throughput)\` |"
    echo "| Buses x $devices saws at $full_rate frames/s with no frame lost at the bridge (samples may be missing) | $(stat throughput throughput_max_buses_frames) | | | \`$(cmd throughput)\` |"
    echo "| CPU for 1 bus at full load (% of a core): bridge; floor = bare Fast DDS writer + bare bus reader | $(stat throughput throughput_cpu_pct_1bus); $(stat throughput throughput_floor_dds_cpu_pct) + $(stat throughput throughput_floor_bus_cpu_pct) | | | \`$(cmd throughput)\` |"
    echo "| Bridge CPU at the largest loss-free N (% of a core) | $(stat throughput throughput_cpu_pct) | | | \`$(cmd throughput)\` |"
    echo "| First N with loss; CPU there (% of a core): bridge / injector / subscriber (these two share the other core(s)) | $(stat throughput throughput_first_fail); $(stat throughput throughput_fail_cpu_pct) / $(stat throughput throughput_fail_inject_cpu_pct) / $(stat throughput throughput_fail_sub_cpu_pct) | | | \`$(cmd throughput)\` |"
    local_row="" ; for n in $buses_list; do v=$(stat throughput throughput_cpu_pct_n$n); [ -z "$v" ] || local_row+="$n: $v; "; done
    echo "| Bridge CPU by N buses (% of its core) | ${local_row%; } | | | \`$(cmd throughput)\` |"
    local_row="" ; for n in $buses_list; do v=$(stat throughput throughput_frames_per_sample_n$n); [ -z "$v" ] || local_row+="$n: $v; "; done
    echo "| Frames per status sample by N (PDO bursts merged, none overwritten) | ${local_row%; } | | | \`$(cmd throughput)\` |"
    local_row="" ; for n in $buses_list; do v=$(stat throughput throughput_samples_per_s_per_bus_n$n); [ -z "$v" ] || local_row+="$n: $v; "; done
    echo "| Status samples per second per bus by N (status_publish ${status_publish:-per_cycle}) | ${local_row%; } | | | \`$(cmd throughput)\` |"
    local_row="" ; for n in $buses_list; do v=$(stat throughput throughput_last_p50_us_n$n); [ -z "$v" ] || local_row+="$n: $v; "; done
    echo "| CAN -> DDS under full load, the last TPDO of a saw's cycle (TPDO2), p50 µs by N | ${local_row%; } | | | \`$(cmd throughput)\` |"
    local_row="" ; for n in $buses_list; do v=$(stat throughput throughput_superseded_n$n); [ -z "$v" ] || local_row+="$n: $v; "; done
    echo "| Status samples the bus process replaced unsent because its DDS process lagged, by N | ${local_row%; } | | | \`$(cmd throughput)\` |"
  fi
  if want scrape; then
    for n in $scrape_buses; do
      echo "| /metrics' cost, $n bus(es) x $devices saws at $full_rate frames/s: bridge CPU (both processes, % of a core) not scraped / scraped every second; the difference | $(stat scrape scrape_plain_n${n}_cpu_pct) / $(stat scrape scrape_scraped_n${n}_cpu_pct); $(stat scrape scrape_cost_n${n}_cpu_pct) | | | \`$(cmd scrape)\` |"
      echo "| /metrics, $n bus(es): CPU per scrape, both processes (ms: 100 back to back after the load, less as long idle); so at one scrape a second (% of a core) | $(stat scrape scrape_scraped_n${n}_cpu_ms_per_scrape); $(stat scrape scrape_scraped_n${n}_cpu_pct_at_1s) | | | \`$(cmd scrape)\` |"
      echo "| /metrics, $n bus(es): scrapes answered / made; answer size (KiB); time per scrape (ms); samples missing not scraped / scraped | $(stat scrape scrape_scraped_n${n}_scrapes_ok) / $(stat scrape scrape_scraped_n${n}_scrapes); $(stat scrape scrape_scraped_n${n}_kib); $(stat scrape scrape_scraped_n${n}_ms); $(stat scrape scrape_plain_n${n}_missing) / $(stat scrape scrape_scraped_n${n}_missing) | | | \`$(cmd scrape)\` |"
    done
  fi
  if want memory; then
    echo "| Memory, $mem_buses x $devices saws at full load, bus + DDS process: PSS (each page once) / VmRSS / VmHWM summed (MiB) | $(stat memory memory_pss_mib) / $(stat memory memory_rss_mib) / $(stat memory memory_hwm_mib) | PSS <= 64 | $(verdict "$(median memory memory_pss_mib)" "<=" 64) | \`$(cmd memory)\` |"
  fi
  if want startup; then
    echo "| Start-up, 1 bus x 1 saw: process start -> first status sample (ms), median (range) of all starts | $(stat startup startup_1x1_first_ms) | <= 1000 | $(verdict "$(median startup startup_1x1_first_ms)" "<=" 1000) | \`$(cmd startup)\` |"
    echo "| Start-up, $mem_buses x $devices saws: -> first status sample (ms) | $(stat startup startup_${mem_buses}x${devices}_first_ms) | <= 1000 | $(verdict "$(median startup startup_${mem_buses}x${devices}_first_ms)" "<=" 1000) | \`$(cmd startup)\` |"
    echo "| Start-up, $mem_buses x $devices saws: -> every saw's first status sample (ms) | $(stat startup startup_${mem_buses}x${devices}_all_ms) | | | \`$(cmd startup)\` |"
    echo "| Start-up with the devices powered (simulator): -> first sample with live data (device booted, online), 1x1 / ${mem_buses}x$devices (ms) | $(stat startup startup_1x1_first_online_ms) / $(stat startup startup_${mem_buses}x${devices}_first_online_ms) | | | \`$(cmd startup)\` |"
    echo "| Start-up with the devices powered: -> every saw online, 1x1 / ${mem_buses}x$devices (ms) | $(stat startup startup_1x1_all_online_ms) / $(stat startup startup_${mem_buses}x${devices}_all_online_ms) | <= 1000 | $(verdict "$(median startup startup_${mem_buses}x${devices}_all_online_ms)" "<=" 1000) | \`$(cmd startup)\` |"
    echo "| Start-up, ${mem_buses}x$devices: when each saw came online (booted the CiA 302-2 way), p10 / p50 / p90 of the $((mem_buses * devices)) (ms) | $(stat startup startup_${mem_buses}x${devices}_online_p10_ms) / $(stat startup startup_${mem_buses}x${devices}_online_p50_ms) / $(stat startup startup_${mem_buses}x${devices}_online_p90_ms) | | | \`$(cmd startup)\` |"
    echo "| Start-up, ${mem_buses}x$devices: when the application discovered the bridge's DDS participant / the first / the last of the $((mem_buses * devices)) status writers; first status sample (ms) | $(stat startup startup_${mem_buses}x${devices}_found_dds_ms) / $(stat startup startup_${mem_buses}x${devices}_found_first_status_writer_ms) / $(stat startup startup_${mem_buses}x${devices}_found_all_status_writers_ms); $(stat startup startup_${mem_buses}x${devices}_first_ms) | | | \`$(cmd startup)\` |"
    echo "| Start-up, ${mem_buses}x$devices: CPU used from the spawn until every saw online (ms): bus process / DDS process / simulator / the application (bench-startup); the window (ms), on $cores cores | $(stat startup startup_${mem_buses}x${devices}_cpu_bus_ms) / $(stat startup startup_${mem_buses}x${devices}_cpu_dds_ms) / $(stat startup startup_${mem_buses}x${devices}_cpu_watched_ms) / $(stat startup startup_${mem_buses}x${devices}_cpu_sub_ms); $(stat startup startup_${mem_buses}x${devices}_cpu_window_ms) | | | \`$(cmd startup)\` |"
    echo "| Memory idle after start-up, bus + DDS process, 1x1 / ${mem_buses}x$devices, master role: PSS (VmRSS summed) (MiB) | $(stat startup startup_1x1_pss_mib) ($(stat startup startup_1x1_rss_mib)) / $(stat startup startup_${mem_buses}x${devices}_pss_mib) ($(stat startup startup_${mem_buses}x${devices}_rss_mib)) | | | \`$(cmd startup)\` |"
  fi
  if want jitter; then
    echo "| Floor: a bare periodic timer (20 ms, absolute clock_nanosleep) on the bridge's core: wake-up lateness p50 / p99 / p99.9 / max (µs) | $(stat jitter jitter_floor_p50_us) / $(stat jitter jitter_floor_p99_us) / $(stat jitter jitter_floor_p999_us) / $(stat jitter jitter_floor_max_us) | | | \`$(cmd jitter)\` |"
    echo "| SYNC jitter, 30 saws, no load (the unloaded figure): deviation from 20 ms p50 / p99 / p99.9 / max (µs); SYNCs seen / expected | $(stat jitter jitter_idle_p50_us) / $(stat jitter jitter_idle_p99_us) / $(stat jitter jitter_idle_p999_us) / $(stat jitter jitter_idle_max_us); $(stat jitter jitter_idle_syncs) / $(stat jitter jitter_idle_expected_syncs) | | | \`$(cmd jitter)\` |"
    echo "| the same, from the times the meter read them | $(stat jitter jitter_idle_read_p50_us) / $(stat jitter jitter_idle_read_p99_us) / $(stat jitter jitter_idle_read_p999_us) / $(stat jitter jitter_idle_read_max_us) | | | |"
    for sc in "quiet:alone" "frozen:with a frozen emergency subscriber" "record:recording to a slow disk"; do
      k=${sc%%:*}
      echo "| SYNC jitter, 30 saws at ${jitter_rate:-$full_rate} frames/s + 1000 EMCY/s, ${sc#*:}: deviation from 20 ms p50 / p99 / p99.9 / max (µs); SYNCs seen / expected | $(stat jitter jitter_${k}_p50_us) / $(stat jitter jitter_${k}_p99_us) / $(stat jitter jitter_${k}_p999_us) / $(stat jitter jitter_${k}_max_us); $(stat jitter jitter_${k}_syncs) / $(stat jitter jitter_${k}_expected_syncs) | | | \`$(cmd jitter)\` |"
      echo "| the same, from the times the meter read them (adds the hub's and the meter's scheduling) | $(stat jitter jitter_${k}_read_p50_us) / $(stat jitter jitter_${k}_read_p99_us) / $(stat jitter jitter_${k}_read_p999_us) / $(stat jitter jitter_${k}_read_max_us) | | | |"
    done
    echo "| SYNC jitter p99.9 under load alone / frozen subscriber / slow disk, over the unloaded figure (µs) | $(stat jitter jitter_quiet_p999_over_idle_us) / $(stat jitter jitter_frozen_p999_over_idle_us) / $(stat jitter jitter_record_p999_over_idle_us) | <= 200 each | quiet $(verdict "$(median jitter jitter_quiet_p999_over_idle_us)" "<=" 200), frozen $(verdict "$(median jitter jitter_frozen_p999_over_idle_us)" "<=" 200), disk $(verdict "$(median jitter jitter_record_p999_over_idle_us)" "<=" 200) | \`$(cmd jitter)\` |"
    echo "| SYNC jitter p99.9 with a frozen subscriber, over the same alone (µs) | $(stat jitter jitter_frozen_p999_over_quiet_us) | <= 200 | $(verdict "$(median jitter jitter_frozen_p999_over_quiet_us)" "<=" 200) | \`$(cmd jitter)\` |"
    echo "| SYNC jitter p99.9 recording to a slow disk, over the same alone (µs) | $(stat jitter jitter_record_p999_over_quiet_us) | <= 200 | $(verdict "$(median jitter jitter_record_p999_over_quiet_us)" "<=" 200) | \`$(cmd jitter)\` |"
    if ((sentinel)); then
      echo "| **Between host stalls** (a sentinel one priority above, on the bridge's core, woke > 500 µs late: periods whose SYNCs came within 2 ms after such a stall left out): | | | | |"
      echo "| Floor between host stalls: p50 / p99 / p99.9 / max (µs); host stalls seen; wake-ups kept / all | $(stat jitter jitter_floor_clean_p50_us) / $(stat jitter jitter_floor_clean_p99_us) / $(stat jitter jitter_floor_clean_p999_us) / $(stat jitter jitter_floor_clean_max_us); $(stat jitter jitter_floor_host_stalls); $(stat jitter jitter_floor_clean_wakeups) / $(stat jitter jitter_floor_wakeups) | | | \`$(cmd jitter)\` |"
      for sc in "idle:no load" "quiet:full load alone" "frozen:full load, frozen subscriber" "record:full load, slow disk"; do
        k=${sc%%:*}
        echo "| SYNC jitter between host stalls, ${sc#*:}: p50 / p99 / p99.9 / max (µs); host stalls seen (stalled ms, longest µs); periods kept | $(stat jitter jitter_${k}_clean_p50_us) / $(stat jitter jitter_${k}_clean_p99_us) / $(stat jitter jitter_${k}_clean_p999_us) / $(stat jitter jitter_${k}_clean_max_us); $(stat jitter jitter_${k}_host_stalls) ($(stat jitter jitter_${k}_host_stalled_ms), $(stat jitter jitter_${k}_host_longest_stall_us)); $(stat jitter jitter_${k}_clean_periods) | | | \`$(cmd jitter)\` |"
      done
      echo "| SYNC jitter p99.9 between host stalls under load alone / frozen subscriber / slow disk, over the unloaded figure (µs) | $(stat jitter jitter_quiet_clean_p999_over_idle_us) / $(stat jitter jitter_frozen_clean_p999_over_idle_us) / $(stat jitter jitter_record_clean_p999_over_idle_us) | <= 200 each | quiet $(verdict "$(median jitter jitter_quiet_clean_p999_over_idle_us)" "<=" 200), frozen $(verdict "$(median jitter jitter_frozen_clean_p999_over_idle_us)" "<=" 200), disk $(verdict "$(median jitter jitter_record_clean_p999_over_idle_us)" "<=" 200) | \`$(cmd jitter)\` |"
      echo "| SYNC jitter p99.9 between host stalls, frozen subscriber / slow disk over the same alone (µs) | $(stat jitter jitter_frozen_clean_p999_over_quiet_us) / $(stat jitter jitter_record_clean_p999_over_quiet_us) | <= 200 each | frozen $(verdict "$(median jitter jitter_frozen_clean_p999_over_quiet_us)" "<=" 200), disk $(verdict "$(median jitter jitter_record_clean_p999_over_quiet_us)" "<=" 200) | \`$(cmd jitter)\` |"
    else
      echo "| **Between host stalls**: not measured (not pinned, or one core: the bridge has no core of its own for the sentinel to watch) | | | | |"
    fi
  fi
  if want soak; then
    echo "| Soak, $soak_s s flood (full load, 1000 EMCY/s, 1000 hostile frames/s): VmRSS start / end / max (MiB) | $(stat soak soak_rss_start_mib) / $(stat soak soak_rss_end_mib) / $(stat soak soak_rss_max_mib) | flat | | \`$(cmd soak)\` |"
    echo "| Soak: open file descriptors start / end / max; bridge alive at the end | $(stat soak soak_fds_start) / $(stat soak soak_fds_end) / $(stat soak soak_fds_max); $(stat soak soak_bridge_alive) | flat | | \`$(cmd soak)\` |"
    echo "| Soak: SYNCs seen / expected; SYNC period deviation p50 / p99 / p99.9 / max (µs) | $(stat soak soak_sync_syncs) / $(stat soak soak_sync_expected_syncs); $(stat soak soak_sync_p50_us) / $(stat soak soak_sync_p99_us) / $(stat soak soak_sync_p999_us) / $(stat soak soak_sync_max_us) | | | \`$(cmd soak)\` |"
    echo "| Soak: service requests sent / answered / refused / unanswered (per s); set values written (per s) | $(stat soak soak_flood_requests_sent) / $(stat soak soak_flood_requests_answered) / $(stat soak soak_flood_requests_refused) / $(stat soak soak_flood_requests_unanswered) ($(stat soak soak_flood_requests_per_s)); $(stat soak soak_flood_setpoints_written) ($(stat soak soak_flood_setpoints_per_s)) | | | \`$(cmd soak)\` |"
    echo "| Soak: the bridge's own counts: requests refused at a full loop queue; commands lost before the bridge | $(stat soak soak_flood_bridge_requests_refused); $(stat soak soak_flood_bridge_commands_lost) | | | \`$(cmd soak)\` |"
  fi
  if want hop; then
    for mw in "unix:core:Unix socket (link::BusChannel -> link::DdsChannel), both processes on one core" \
              "unix:spread:Unix socket, processes spread over the cores" \
              "iceoryx:core:iceoryx publisher/subscriber (RouDi), both processes on one core" \
              "iceoryx:spread:iceoryx, processes spread over the cores"; do
      m=${mw%%:*}; rest=${mw#*:}; where=${rest%%:*}; k="hop_${m}_${where}"
      [ -n "$(stat hop ${k}_samples)" ] || { echo "| Channel hop, ${rest#*:}: not measured (not built: -DLINEBRIDGE_BENCH_ICEORYX=ON, iox-roudi) | | | | |"; continue; }
      echo "| Channel hop, ${rest#*:}: bus->DDS p50 / p99 / p99.9; DDS->bus p50 / p99; round trip p50 / p99 (µs); lost | $(stat hop ${k}_bus2dds_p50_us) / $(stat hop ${k}_bus2dds_p99_us) / $(stat hop ${k}_bus2dds_p999_us); $(stat hop ${k}_dds2bus_p50_us) / $(stat hop ${k}_dds2bus_p99_us); $(stat hop ${k}_rtt_p50_us) / $(stat hop ${k}_rtt_p99_us); $(stat hop ${k}_lost) | | | \`$(cmd hop)\` |"
    done
  fi
  if want hopjitter; then
    for sc in "quiet:load alone" "observers:+ 20 observer participants" "flood:+ forged discovery flood"; do
      k=${sc%%:*}
      for what in bridge:split single:single; do
        w=${what%%:*}; p="hopjitter_${k}_${w}"
        echo "| SYNC jitter, secured line, 30 saws at ${jitter_rate:-$full_rate} frames/s + 1000 EMCY/s ${sc#*:}, ${what#*:}: p50 / p99 / p99.9 / max (µs); SYNCs seen / expected; CPU all / bus process (% of a core); alive | $(stat hopjitter ${p}_p50_us) / $(stat hopjitter ${p}_p99_us) / $(stat hopjitter ${p}_p999_us) / $(stat hopjitter ${p}_max_us); $(stat hopjitter ${p}_syncs) / $(stat hopjitter ${p}_expected_syncs); $(stat hopjitter ${p}_cpu_pct) / $(stat hopjitter ${p}_bus_cpu_pct); $(stat hopjitter ${p}_bridge_alive) | | | \`$(cmd hopjitter)\` |"
      done
    done
  fi
  if want security; then
    for what in "dds:bare Fast DDS hop, $devices status topics at $lat_rate samples/s" "can2dds:CAN->DDS through the bridge" \
                "dds2can:DDS->CAN set value through the bridge"; do
      k=${what%%:*}
      echo "| Security: ${what#*:}, p50 / p99 / p99.9 (µs): unsecured; secured | $(stat security security_plain_${k}_p50_us) / $(stat security security_plain_${k}_p99_us) / $(stat security security_plain_${k}_p999_us); $(stat security security_secured_${k}_p50_us) / $(stat security security_secured_${k}_p99_us) / $(stat security security_secured_${k}_p999_us) | | | \`$(cmd security)\` |"
    done
    echo "| Security: bridge CPU, CAN->DDS at $lat_rate frames/s, 1 bus x $devices saws (% of a core): unsecured; secured | $(stat security security_plain_bridge_cpu_pct); $(stat security security_secured_bridge_cpu_pct) | | | \`$(cmd security)\` |"
    echo "| Security: CAN->DDS samples missing + DDS->CAN set values lost: unsecured; secured | $(stat security security_plain_missing); $(stat security security_secured_missing) | 0 | $(verdict "$(median security security_secured_missing)" "<=" 0) | \`$(cmd security)\` |"
    echo "| Security: start-up 1 saw, process start -> first status sample (ms): unsecured; secured | $(stat security security_plain_startup_first_ms); $(stat security security_secured_startup_first_ms) | | | \`$(cmd security)\` |"
    echo "| Security: start-up 1 saw, process start -> saw online (ms): unsecured; secured | $(stat security security_plain_startup_online_ms); $(stat security security_secured_startup_online_ms) | | | \`$(cmd security)\` |"
  fi
} >"$table"

{
  if ((report_only)); then
    echo "linebridge benchmarks: table re-printed from $out_dir ($runs run(s)), measured $(date -u -r "$out_dir/commands.txt" '+%Y-%m-%d %H:%M UTC')"
  else
    echo "linebridge benchmarks, $(date -u '+%Y-%m-%d %H:%M UTC'), $runs run(s)$quick_flag, $(($(date +%s) - begin)) s"
  fi
  echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1), $cores cores, $(uname -r), $(awk '/MemTotal/ { printf "%.0f GiB", $2 / 1048576 }' /proc/meminfo) RAM"
  echo "niceness of every bench process: $(nice)"
  echo "DDS transport: $([ -n "${LINEBRIDGE_BENCH_SHARED_MEMORY:-}" ] && echo "UDP on loopback + shared memory (--shared-memory)" || echo "UDP on loopback only")"
  ((report_only)) || echo "load average (1/5/15 min) before: $load_before, after: $(cut -d' ' -f1-3 /proc/loadavg)"
  echo
  column -t -s '|' -o '|' "$table"
  echo
  echo "raw data, logs and every process's command line: $out_dir (commands.txt)"
} | tee "$out_dir/summary.txt"
