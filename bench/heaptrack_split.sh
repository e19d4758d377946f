#!/usr/bin/env bash
# Heap profile of the split bridge (issue 27): B buses x N saws played by linebridge-sim, the bus
# process (`linebridge --part bus`) and the DDS process (`linebridge --part dds`) started by hand on
# one channel, each under heaptrack (Debian's heaptrack 1.4), for --duration seconds; or, with
# --single, `linebridge --part single` under heaptrack. Prints each profile's summary and its top
# allocation sites (peak memory, by our frames where heaptrack_print names them).
# Runs itself inside launch_scripts/netns-run.sh (no DDS participant in the machine's namespace).
#
#   bench/heaptrack_split.sh [--buses B] [--devices N] [--duration S] [--single] [--build-dir DIR] [--out DIR]
#                            [--profiles-file XML]   (the line file's dds.profiles_file)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
buses=8; devices=30; duration=25; single=0; build_dir="$root/build"; out=""; profiles=""
orig=("$@")
. "$root/bench/probe_common.sh"
while (($#)); do
  if probe_option "$1" "${2:-}"; then shift 2; continue; fi
  case "$1" in
    --duration) duration=$2; shift ;;
    --single) single=1 ;;
    -h|--help) probe_usage; exit 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
probe_in_netns lb-heaptrack "${orig[@]}"
app="$build_dir/bridge/app"
d="$out/${buses}x${devices}"; mkdir -p "$d"
"$build_dir/bench/bench-config" --buses "$buses" --devices "$devices" --domain 12 --prefix "ht-$RANDOM" --role master >"$d/line.yaml"
[ -z "$profiles" ] || sed -i "s|^dds:$|dds:\n  profiles_file: '$profiles'|" "$d/line.yaml"
"$app/linebridge-sim" --config "$d/line.yaml" >"$d/sim.out" 2>&1 &
sim=$!
sleep 1
pids=()
if ((single)); then
  heaptrack -o "$d/single" "$app/linebridge" --part single --config "$d/line.yaml" --duration "$duration" >"$d/single.out" 2>&1 &
  pids+=($!)
else
  ch="$d/channel.sock"
  heaptrack -o "$d/bus" "$app/linebridge" --part bus --channel "$ch" --config "$d/line.yaml" --duration "$duration" >"$d/bus.out" 2>&1 &
  pids+=($!)
  heaptrack -o "$d/dds" "$app/linebridge" --part dds --channel "$ch" --config "$d/line.yaml" --duration "$duration" >"$d/dds.out" 2>&1 &
  pids+=($!)
fi
for p in "${pids[@]}"; do wait "$p" || true; done
kill -TERM $sim 2>/dev/null || true
wait $sim 2>/dev/null || true
for f in "$d"/*.zst "$d"/*.gz; do
  [ -f "$f" ] || continue
  heaptrack_print -f "$f" --print-peaks 1 --print-allocators 0 --print-temporary 0 --print-leaks 0 \
    --peak-limit 40 --sub-peak-limit 8 >"${f%%.*}.txt" 2>&1 || true
  echo "== $(basename "$f")"
  grep -E '^(peak heap memory consumption|peak RSS|total memory leaked|calls to allocation functions|total runtime)' "${f%%.*}.txt" || true
done
echo "raw: $d"
