#!/usr/bin/env bash
# Resident memory of both processes of the split bridge at full load (issue 27): the memory
# figure's setup (bench.sh fig_memory -> throughput_step: monitor role, B buses x N saws injected at
# 8000 frames/s per bus, a subscriber of every status topic, the bridge pinned to the last core),
# but sampling the bus process (what bench.sh reports), the DDS process it starts (what it does not)
# and their sum, as VmRSS and as Pss (smaps_rollup: shared library pages split between the two).
# Runs itself inside launch_scripts/netns-run.sh.
#
#   bench/probe_memory_load.sh [--buses B] [--devices N] [--seconds S] [--part both|single]
#                              [--profiles-file XML] [--build-dir DIR] [--out DIR]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
buses=8; devices=30; seconds=10; part=both; profiles=""; build_dir="$root/build"; out=""
orig=("$@")
. "$root/bench/probe_common.sh"
while (($#)); do
  if probe_option "$1" "${2:-}"; then shift 2; continue; fi
  case "$1" in
    --seconds) seconds=$2; shift ;;
    --part) part=$2; shift ;;
    -h|--help) probe_usage; exit 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
probe_in_netns lb-memload "${orig[@]}"
bin="$build_dir/bench"; app="$build_dir/bridge/app"
cores=$(nproc); pin=(taskset -c $((cores - 1))); harness=(taskset -c 0-$((cores - 2)))
d="$out/${buses}x${devices}-$part${profiles:+-$(basename "$profiles" .xml)}"; mkdir -p "$d"
p="ml-$RANDOM"; count=$((8000 * seconds))
"$bin/bench-config" --buses "$buses" --devices "$devices" --domain 13 --prefix "$p" --role monitor >"$d/line.yaml"
[ -z "$profiles" ] || sed -i "s|^dds:$|dds:\n  profiles_file: '$profiles'|" "$d/line.yaml"
started=()
cleanup() { for x in "${started[@]}"; do kill -TERM "$x" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT
"${harness[@]}" "$bin/bench-inject" --buses "$buses" --devices "$devices" --rate 8000 --count $count --prefix "$p" \
  --ready "$d/inject.ready" --go "$d/go" --stop "$d/stop" --linger 120 >"$d/inject.out" 2>"$d/inject.err" &
inj=$!; started+=($inj)
while [ ! -e "$d/inject.ready" ]; do sleep 0.05; done
"${harness[@]}" "$bin/bench-status-sub" --buses "$buses" --devices "$devices" --domain 13 --expect $((count * buses)) \
  --diagnostics --ready "$d/sub.ready" --timeout $((seconds * 4 + 120)) >"$d/sub.out" 2>"$d/sub.err" &
sub=$!; started+=($sub)
"${pin[@]}" "$app/linebridge" --config "$d/line.yaml" --part "$part" >"$d/bridge.out" 2>&1 &
br=$!; started+=($br)
while [ ! -e "$d/sub.ready" ]; do sleep 0.05; done
sleep 0.5
touch "$d/go"
sleep $((seconds / 2))
child=$(cat /proc/$br/task/*/children 2>/dev/null | tr ' ' '\n' | sed -n 1p || true)
kib() { awk -v k="$2:" '$1 == k { print $2 }' "$1"; }
{
  for who in bus:$br dds:${child:-}; do
    name=${who%%:*}; pid=${who#*:}
    [ -n "$pid" ] || continue
    cp /proc/$pid/status "$d/$name.status"; cp /proc/$pid/smaps_rollup "$d/$name.rollup"
    echo "$name pid $pid: VmRSS $(kib "$d/$name.status" VmRSS) kB, VmHWM $(kib "$d/$name.status" VmHWM) kB, RssAnon $(kib "$d/$name.status" RssAnon) kB, RssFile $(kib "$d/$name.status" RssFile) kB, Pss $(kib "$d/$name.rollup" Pss) kB, threads $(kib "$d/$name.status" Threads)"
  done
} | tee "$d/memory.txt"
awk '/VmRSS/ { r += $5; h += $8; p += $17 } END { printf "sum: VmRSS %.1f MiB, VmHWM %.1f MiB, Pss %.1f MiB\n", r / 1024, h / 1024, p / 1024 }' "$d/memory.txt" | tee -a "$d/memory.txt"
while [ ! -s "$d/inject.out" ] && kill -0 $inj 2>/dev/null; do sleep 0.1; done
wait $sub 2>/dev/null || true
touch "$d/stop"
echo "inject: $(grep -E 'inject_rate_per_bus|inject_frames_sent' "$d/inject.out" | tr '\n' ' ')"
echo "subscriber: $(grep -E 'sub_stamped|bridge_frames_in|bridge_error_frames' "$d/sub.out" | tr '\n' ' ')"
echo "raw: $d"
