#!/usr/bin/env bash
# Where a line's memory and boot time go (issue 27): one start of the real split `linebridge`
# (master role) with `linebridge-sim` playing B buses x N saws, measured the way bench.sh's startup
# figure is (bench-startup: process start -> every saw's first sample, and first sample online), and
# beside it what the figure does not show:
#   - per process (the bus process bench.sh counts, and the DDS process it starts): VmRSS, RssAnon,
#     RssFile, RssShmem, VmHWM, smaps_rollup, threads by name, the largest mappings;
#   - /dev/shm (Fast DDS's shared-memory segments: the namespace's private one);
#   - bus 0 recorded (record:): SDO transfers per node on the bus, their round trips, and each
#     node's boot span (first SDO request -> NMT start) and its gaps;
#   - the bridge's log: each saw's "checked, configured ... and started" time from the process start.
# Runs itself inside launch_scripts/netns-run.sh (no DDS participant in the machine's namespace).
#
#   bench/probe_boot_memory.sh [--buses B] [--devices N] [--build-dir DIR] [--out DIR]
#                              [--settle S] [--log-level L] [--part both|single] [--profiles-file XML]
# --profiles-file: the line file's dds.profiles_file (a site's Fast DDS XML profiles), e.g.
# bench/profiles/dynamic-payloads.xml.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
buses=8; devices=30; build_dir="$root/build"; out=""; settle=12; log_level=info; part=both; profiles=""
orig=("$@")
. "$root/bench/probe_common.sh"
while (($#)); do
  if probe_option "$1" "${2:-}"; then shift 2; continue; fi
  case "$1" in
    --settle) settle=$2; shift ;;
    --log-level) log_level=$2; shift ;;
    --part) part=$2; shift ;;
    -h|--help) probe_usage; exit 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
probe_in_netns lb-probe "${orig[@]}"
bin="$build_dir/bench"; app="$build_dir/bridge/app"
spec="${buses}x${devices}-$part${profiles:+-$(basename "$profiles" .xml)}"
d="$out/$spec"; mkdir -p "$d"
rm -f "$d/bus0.log"
"$bin/bench-config" --buses "$buses" --devices "$devices" --domain 11 --prefix "probe-$spec-$RANDOM" --role master \
  --record "$d/bus0.log" >"$d/line.yaml"
[ -z "$profiles" ] || sed -i "s|^dds:$|dds:\n  profiles_file: '$profiles'|" "$d/line.yaml"
"$app/linebridge-sim" --config "$d/line.yaml" >"$d/sim.out" 2>&1 &
sim=$!
bs=""
# Whatever happens below, the simulator and bench-startup (which stops the bridge) end with this script.
trap 'for x in $sim $bs; do kill -TERM "$x" 2>/dev/null || true; done' EXIT
sleep 1
# bench-startup reads memory after --settle and stops the bridge; meanwhile this script samples both
# processes of the bridge (bench-startup's child and grandchild) once the boot is over.
"$bin/bench-startup" --online --buses "$buses" --devices "$devices" --domain 11 --settle "$settle" \
  --log "$d/bridge.log" -- "$app/linebridge" --config "$d/line.yaml" --log-level "$log_level" --part "$part" >"$d/startup.out" 2>"$d/startup.err" &
bs=$!
# Wait for the bus process and its DDS process.
bus_pid=""; dds_pid=""
for _ in $(seq 200); do
  bus_pid=$(cat /proc/$bs/task/*/children 2>/dev/null | tr ' ' '\n' | sed -n 1p)
  [ -n "$bus_pid" ] && [ "$part" = single ] && break
  [ -n "$bus_pid" ] && dds_pid=$(cat /proc/"$bus_pid"/task/*/children 2>/dev/null | tr ' ' '\n' | sed -n 1p || true)
  [ -n "$dds_pid" ] && break
  sleep 0.05
done
# PERF_DDS=S: perf record (call graphs) of the DDS process for its first S seconds (its endpoints'
# creation), report in dds.perf.txt.
perf_pid=""
if [ -n "${PERF_DDS:-}" ] && [ -n "$dds_pid" ]; then
  perf record -F 999 -g -p "$dds_pid" -o "$d/dds.perf" -- sleep "$PERF_DDS" >"$d/dds.perf.log" 2>&1 &
  perf_pid=$!
fi
# Sample when bench-startup saw every saw online (its report is written only at the end, so: the
# log's last "started" line, then half the settle time).
for _ in $(seq 300); do
  n=$(grep -c 'and started' "$d/bridge.log" 2>/dev/null || true)
  [ "${n:-0}" -ge $((buses * devices)) ] && break
  sleep 0.1
done
# ... and the DDS process has created every endpoint (its "ready" line), then a second more.
for _ in $(seq 300); do
  [ "$part" = single ] && break
  grep -q 'DDS side of line .* ready' "$d/bridge.log" 2>/dev/null && break
  sleep 0.1
done
sleep 1
snap() {  # NAME PID
  local name=$1 pid=$2 f="$d/$1.proc"
  {
    echo "== $name pid $pid: $(tr '\0' ' ' </proc/$pid/cmdline)"
    grep -E '^(VmPeak|VmSize|VmLck|VmHWM|VmRSS|RssAnon|RssFile|RssShmem|VmData|VmStk|Threads)' /proc/$pid/status
    echo "-- smaps_rollup"; cat /proc/$pid/smaps_rollup
    echo "-- threads by name (count name)"
    for t in /proc/$pid/task/*; do cat $t/comm; done | sed 's/[0-9]*$//' | sort | uniq -c | sort -rn
    echo "-- largest mappings by Rss (kB, mapping)"
    awk '/^[0-9a-f]+-[0-9a-f]+ /{m=$0} /^Rss:/{print $2, m}' /proc/$pid/smaps | sort -rn | sed -n 1,25p
  } >"$f"
  cp /proc/$pid/smaps "$d/$1.smaps"
}
ticks() { awk '{ sub(/.*\) /, ""); printf "%.2f", ($12 + $13) / 100 }' "/proc/$1/stat"; }
[ -n "$bus_pid" ] && echo "cpu_s bus $(ticks "$bus_pid")" >"$d/cpu.txt"
[ -n "$dds_pid" ] && echo "cpu_s dds $(ticks "$dds_pid")" >>"$d/cpu.txt"
[ -n "$bus_pid" ] && snap bus "$bus_pid"
[ -n "$dds_pid" ] && snap dds "$dds_pid"
snap sim "$sim"
{ echo "== /dev/shm"; ls -la /dev/shm; du -sk /dev/shm; } >"$d/shm.txt" 2>&1
wait $bs || true
if [ -n "$perf_pid" ]; then
  wait "$perf_pid" || true
  perf report -i "$d/dds.perf" --no-children --sort dso,sym --stdio -g none 2>/dev/null | grep '%' | sed -n 1,40p >"$d/dds.perf.txt" || true
  perf report -i "$d/dds.perf" --children --sort sym --stdio -g none 2>/dev/null | grep '%' | sed -n 1,60p >"$d/dds.perf-children.txt" || true
fi
kill -TERM $sim 2>/dev/null || true
wait $sim 2>/dev/null || true

# ---- analysis -------------------------------------------------------------------------------------
echo "== $spec: bench-startup"; cat "$d/startup.out"
for p in bus dds sim; do
  [ -f "$d/$p.proc" ] || continue
  echo "== $p: $(grep -E '^(VmRSS|RssAnon|RssFile|RssShmem|VmHWM|Threads)' "$d/$p.proc" | tr -s ' \t' ' ' | tr '\n' ';')"
done
echo "== /dev/shm: $(tail -1 "$d/shm.txt")"
cat "$d/cpu.txt" 2>/dev/null || true
for p in bus dds sim; do [ -f "$d/$p.smaps" ] && python3 "$root/bench/smaps_kinds.py" "$d/$p.smaps" "$p"; done
# Boot times from the log (spdlog %H:%M:%S.%e), from the first line the bus process wrote.
python3 - "$d/bridge.log" "$d/bus0.log" "$devices" <<'EOF'
import re, sys, statistics as st
log, rec, devices = sys.argv[1], sys.argv[2], int(sys.argv[3])
def t(s):
    h, m, x = s.split(':'); return (int(h) * 3600 + int(m) * 60 + float(x)) * 1000
lines = open(log, errors='replace').read().splitlines()
t0 = None; started = []
for l in lines:
    m = re.match(r'(\d\d:\d\d:\d\d\.\d\d\d) \[bridge\]', l)
    if not m: continue
    if t0 is None: t0 = t(m.group(1))
    if 'checked, configured' in l and 'and started' in l:
        started.append(t(m.group(1)) - t0)
def q(v, p): v = sorted(v); return v[min(len(v) - 1, int(p / 100 * len(v)))]
marks = {}
for l in lines:
    m = re.match(r'(\d\d:\d\d:\d\d\.\d\d\d) \[(bridge|dds)\]', l)
    if not m or t0 is None: continue
    for key, pat in (('DDS process started', 'DDS process started'), ('DDS side connected', 'DDS side connected'),
                     ('DDS side ready (every endpoint created)', 'DDS side of line'), ('first DDS-process line', '[dds]')):
        if pat in l and key not in marks: marks[key] = t(m.group(1)) - t0
print("== log: ms after the bridge's first log line: " + "; ".join(f"{k} {v:.0f}" for k, v in sorted(marks.items(), key=lambda x: x[1])))
if started:
    print(f"== log: saws started {len(started)}; ms after the bridge's first log line: min {min(started):.0f} "
          f"p10 {q(started,10):.0f} p50 {q(started,50):.0f} p90 {q(started,90):.0f} max {max(started):.0f}")
    hist = {}
    for s in started: hist[int(s // 100) * 100] = hist.get(int(s // 100) * 100, 0) + 1
    print("   started per 100 ms: " + ", ".join(f"{k}-{k+99}: {v}" for k, v in sorted(hist.items())))
# Bus 0's recording: SDO requests 600h+n, answers 580h+n, NMT 000h, heartbeats 700h+n.
fr = []
for l in open(rec, errors='replace'):
    m = re.match(r'\((\d+\.\d+)\) \S+ ([0-9A-F]+)#([0-9A-FR]*)', l)
    if m: fr.append((float(m.group(1)) * 1000, int(m.group(2), 16), m.group(3)))
if not fr: sys.exit()
T0 = fr[0][0]
req = {}; rsp = {}; start = {}; rtt = []; pending = {}; gaps = []
for ts, cid, data in fr:
    if 0x601 <= cid <= 0x67F:
        n = cid - 0x600; req.setdefault(n, []).append(ts); pending[n] = ts
    elif 0x581 <= cid <= 0x5FF:
        n = cid - 0x580; rsp.setdefault(n, []).append(ts)
        if n in pending: rtt.append(ts - pending.pop(n))
    elif cid == 0 and data[:2] == '01':
        n = int(data[2:4], 16); start.setdefault(n, ts)
nodes = sorted(req)
print(f"== bus 0 recording: {len(fr)} frames over {fr[-1][0]-T0:.0f} ms; nodes with SDO: {len(nodes)}")
per = [len(req[n]) for n in nodes]
print(f"   SDO requests per node (each an expedited transfer or a segment): min {min(per)} max {max(per)} total {sum(per)}")
print(f"   SDO round trip request->answer (ms): p50 {q(rtt,50):.2f} p90 {q(rtt,90):.2f} p99 {q(rtt,99):.2f} max {max(rtt):.2f}")
# Time between an answer and the same node's next request (the client's turn-around).
turn = []
for n in nodes:
    a = rsp.get(n, []); r = req[n]
    for x in a:
        nxt = [y for y in r if y > x]
        if nxt: turn.append(nxt[0] - x)
if turn: print(f"   answer -> same node's next request (ms): p50 {q(turn,50):.2f} p90 {q(turn,90):.2f} max {max(turn):.2f}")
first_req = min(min(req[n]) for n in nodes)
concur = 0
# How many nodes had a request in flight at once (sampled at each request).
spans = []
for n in nodes:
    if n in start:
        spans.append((n, min(req[n]) - first_req, start[n] - min(req[n]), start[n] - first_req))
if spans:
    print(f"   first SDO of bus 0 at {first_req - T0:.0f} ms into the recording (the recording starts with the bus)")
    s1 = [s[1] for s in spans]; s2 = [s[2] for s in spans]; s3 = [s[3] for s in spans]
    print(f"   node's first SDO after the bus's first (ms): min {min(s1):.0f} p50 {q(s1,50):.0f} max {max(s1):.0f}")
    print(f"   node's first SDO -> its NMT start (ms): min {min(s2):.0f} p50 {q(s2,50):.0f} max {max(s2):.0f}")
    print(f"   bus's first SDO -> node's NMT start (ms): min {min(s3):.0f} p50 {q(s3,50):.0f} max {max(s3):.0f}")
    # The last SDO answer before NMT start -> NMT start: the wait for a heartbeat after the configuration.
    hb = []
    for n, *_ in spans:
        before = [x for x in rsp.get(n, []) if x < start[n]]
        if before: hb.append(start[n] - max(before))
    print(f"   last SDO answer before NMT start -> NMT start (ms, the heartbeat wait): p50 {q(hb,50):.0f} max {max(hb):.0f}")
    after = [len([x for x in req[n] if x > start[n]]) for n, *_ in spans]
    print(f"   SDO request frames after NMT start per node: {min(after)}..{max(after)}")
# Transfers (initiate frames: upload 40h, download 2xh) per node, by object, before and after its NMT start.
xfer = {}
for ts, cid, data in fr:
    if 0x601 <= cid <= 0x67F and len(data) >= 8:
        cmd = int(data[0:2], 16)
        if cmd == 0x40 or (cmd & 0xE0) == 0x20:
            n = cid - 0x600
            obj = f"{data[4:6]}{data[2:4]}h:{data[6:8]}"
            kind = 'r' if cmd == 0x40 else 'w'
            phase = 'boot' if n not in start or ts <= start[n] else 'after'
            xfer.setdefault(n, []).append((ts, phase, kind + ' ' + obj))
if xfer:
    nb = [len([x for x in v if x[1] == 'boot']) for v in xfer.values()]
    na = [len([x for x in v if x[1] == 'after']) for v in xfer.values()]
    print(f"   SDO transfers per node before its NMT start: min {min(nb)} max {max(nb)}; after: min {min(na)} max {max(na)}")
    n0 = sorted(xfer)[0]
    print(f"   node {n0}, transfers before NMT start, in order: " + ", ".join(x[2] for x in xfer[n0] if x[1] == 'boot'))
    aft = {}
    for x in xfer[n0]:
        if x[1] == 'after': aft[x[2]] = aft.get(x[2], 0) + 1
    print(f"   node {n0}, transfers after NMT start (object: count): " + ", ".join(f"{k}: {v}" for k, v in sorted(aft.items())))
# Frames on the bus per 100 ms during the boot (load on the virtual bus)
EOF
echo "raw: $d"
