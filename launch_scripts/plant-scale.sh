#!/usr/bin/env bash
# A line's DDS side at plant scale and under a forged-discovery flood (issue 41 points 1 and 2),
# the long form of what tests/integration/test_discovery_flood.cpp checks in CI. In a private network
# namespace: the real linebridge-sim and linebridge (one saw, SYNC 20 ms), then
#   1. the honest crowd: --readers applications reading saw1's status through the product's client
#      code (on a secured line each with one of --identities observer identities, in turn) and
#      --bystanders applications with no identity, for --honest-s seconds;
#   2. for each of --rates: forged announcements (bench-forged-announcements: a real secured
#      participant's announcement with random GUID prefixes, announcing --lease-s, each sent --repeat
#      times) for --flood-s seconds, then --after-s seconds of quiet.
# Throughout, long-running clients started before everything: `linebridge-cli echo saw1 status`
# (samples every 5 s) and an application built on ServiceClient (bench-plant-participants with one
# reader and an SDO read every second: answers every 5 s). Printed per phase and per 5 s: the DDS
# process's restarts, its resident memory and CPU, the echo's samples, the client's answers.
#   launch_scripts/plant-scale.sh [--build DIR] [--unsecured [--discovery-server]] [--readers N]
#       [--bystanders M] [--identities N] [--honest-s S] [--rates "1 5 40 2000"] [--flood-s S]
#       [--after-s S] [--lease-s S] [--repeat N] [--flood-target multicast|server|bridge] [--keep]
#   launch_scripts/plant-scale.sh --report DIR    (a run kept with --keep, reported again)
# --build DIR: the build whose programs run (default build). --unsecured: a line without DDS
# Security (the flood replays an unsecured announcement); --discovery-server: its participants are
# clients of a fast-discovery-server (127.0.0.1:11811) instead of multicast discovery.
# --flood-target: where the forged announcements go: the domain's discovery multicast (default),
# the discovery server, or the bridge's own discovery port (7410 + 250 x domain: what an attacker
# sends when multicast is off). Only inside a private network namespace (it re-runs itself through
# launch_scripts/netns-run.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

# What a run (its directory) saw: per phase and per 5 s. `plant-scale.sh --report DIR` again on a
# kept one.
report() {
  python3 - "$1" <<'PY'
import os, re, sys, datetime
d = sys.argv[1]
def lines(name):
    p = os.path.join(d, name)
    return open(p, errors="replace").read().splitlines() if os.path.exists(p) else []
marks = [(float(l.split(" ", 1)[0]), l.split(" ", 1)[1]) for l in lines("marks")]
params = dict(kv.split("=") for kv in (lines("params") or [""])[0].split())
after_s = float(params.get("after_s", 60))
t0 = marks[0][0]
echo = [float(l.split(" ", 1)[0]) for l in lines("echo.out")]
dds = [tuple(map(float, l.split())) for l in lines("dds.samples") if len(l.split()) == 4]
end = marks[-1][0] if marks[-1][1] == "end" else max([marks[-1][0]] + echo[-1:] + [x[0] for x in dds[-1:]])
client = {}
for l in lines("client.out"):
    m = re.match(r"at=([\d.]+) .*samples=(\d+) served=\S+ answered=(\d+)/(\d+) known0=(-?\d+)", l)
    if m: client[int((float(m.group(1)) - t0) // 5)] = (int(m.group(2)), m.group(3) + "/" + m.group(4), m.group(5))
# Restarts: the bus process's log, local wall-clock times of day.
day0 = datetime.datetime.fromtimestamp(t0).replace(hour=0, minute=0, second=0, microsecond=0).timestamp()
restarts = []
for l in lines("bridge.log"):
    if "a new DDS process starts" in l:
        h, m_, s_ = l.split(" ", 1)[0].split(":")
        t = day0 + int(h) * 3600 + int(m_) * 60 + float(s_)
        restarts.append(t if t >= t0 - 60 else t + 86400)
phases = []
for i, (t, what) in enumerate(marks):
    if what.startswith("honest crowd:"):
        stop = next((u for u, w in marks[i:] if w == "honest crowd done"), end)
        phases.append(("honest crowd", t, stop))
    m = re.match(r"flood at (\S+) for", what)
    if m:
        stop = next((u for u, w in marks[i:] if w.startswith("flood at " + m.group(1) + " ended")), end)
        phases.append(("flood " + m.group(1), t, stop))
        phases.append(("after flood " + m.group(1), stop, min(stop + after_s, end)))
hz = os.sysconf("SC_CLK_TCK")
print("--- per phase ---")
for name, a, b in phases:
    r = sum(1 for t in restarts if a <= t < b)
    e = sum(1 for t in echo if a <= t < b)
    s = [x for x in dds if a <= x[0] < b]
    rss = max((x[2] for x in s), default=0) / 1024
    pids = {x[1] for x in s}
    cpu = "%.0f%%" % (100 * (s[-1][3] - s[0][3]) / hz / (s[-1][0] - s[0][0])) if len(s) > 1 and len(pids) == 1 else "n/a (restarted)"
    print("phase %-22s %5.0f s: DDS restarts %d, DDS RSS max %.1f MiB, DDS CPU %s, echo samples %d" % (name, b - a, r, rss, cpu, e))
print("--- per 5 s: echo samples; the ServiceClient application: status samples, SDO reads answered/asked, remote participants it knows; DDS restarts ---")
bins = int((end - t0) // 5) + 1
mk = {}
for t, w in marks:
    mk.setdefault(int((t - t0) // 5), []).append(w)
for b in range(bins):
    a = t0 + 5 * b
    e = sum(1 for t in echo if a <= t < a + 5)
    r = sum(1 for t in restarts if a <= t < a + 5)
    c = client.get(b)
    cs = "samples %4d answered %5s known %3s" % c if c else " " * 33
    print("%6d s  echo %4d  %s  restarts %d%s" % (5 * b, e, cs, r, "".join(" <- " + w for w in mk.get(b, []))))
print("--- totals ---")
print("DDS restarts: %d" % len(restarts))
for l in lines("crowd.out"):
    if l.startswith("readers=") or l.startswith("never_served="): print("crowd: " + l)
news = {}
for l in lines("bridge.log"):
    m = re.search(r"\[dds\] (?:warning|error) (discovery: .*|.*remote DDS participants.*)", l)
    if m: news[re.sub(r"\d+", "N", m.group(1))] = news.get(re.sub(r"\d+", "N", m.group(1)), 0) + 1
for k, v in sorted(news.items(), key=lambda kv: -kv[1])[:6]: print("bridge log (%dx): %s" % (v, k[:200]))
PY
}
if [ "${1:-}" = --report ]; then report "${2:?--report DIR}"; exit 0; fi

build=build
secured=1
discovery_server=0
flood_target=multicast
readers=100
bystanders=0
honest_s=60
rates="1 5 40 2000"
flood_s=60
after_s=60
lease_s=300
repeat=1
keep=0
identities=16
args=("$@")
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --unsecured) secured=0; shift ;;
    --discovery-server) discovery_server=1; shift ;;
    --flood-target) flood_target=$2; shift 2 ;;
    --readers) readers=$2; shift 2 ;;
    --bystanders) bystanders=$2; shift 2 ;;
    --honest-s) honest_s=$2; shift 2 ;;
    --rates) rates=$2; shift 2 ;;
    --flood-s) flood_s=$2; shift 2 ;;
    --after-s) after_s=$2; shift 2 ;;
    --lease-s) lease_s=$2; shift 2 ;;
    --repeat) repeat=$2; shift 2 ;;
    --identities) identities=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    -h|--help) sed -n '2,25p' "$0"; exit 0 ;;
    *) echo "plant-scale.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
if [ "${LINEBRIDGE_NETNS:-}" != 1 ]; then
  exec ./launch_scripts/netns-run.sh "$0" "${args[@]}"
fi

[[ $build = /* ]] || build=$PWD/$build
bin=$build/bridge/app
bench=$build/bench
for b in "$bin/linebridge" "$bin/linebridge-sim" "$bin/linebridge-cli" "$bench/bench-forged-announcements" \
  "$bench/bench-plant-participants"; do
  [ -x "$b" ] || { echo "plant-scale.sh: $b missing (cmake --build $build --target ...)" >&2; exit 2; }
done
dir=$(mktemp -d /tmp/plant-scale.XXXXXX)
domain=$((60 + RANDOM % 100))
pids=()
cleanup() {
  local i
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do kill -TERM "${pids[i]}" 2>/dev/null || true; done
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do wait "${pids[i]}" 2>/dev/null || true; done
  ((keep)) && echo "plant-scale.sh: files kept in $dir" || rm -rf "$dir"
}
trap cleanup EXIT


now() { printf '%s' "${EPOCHREALTIME}"; }
t0=$(now)
rel() { awk -v a="$1" -v b="$t0" 'BEGIN { printf "%.1f", a - b }'; }
mark() { echo "$(now) $*" >>"$dir/marks"; echo "[$(rel "$(now)") s] $*"; }

devices="  - {name: saw1, bus: b, node_id: 5, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 400,
     simulation: {heartbeat_period_ms: 100}}"
ds_keys=""
if ((discovery_server)); then
  ((!secured)) || { echo "plant-scale.sh: --discovery-server needs --unsecured (Fast DDS 2.9.1: no secured line through a discovery server)" >&2; exit 2; }
  ds_keys=", discovery_servers: [{id: 0, address: 127.0.0.1, port: 11811}]"
  fast-discovery-server -i 0 -l 127.0.0.1 -p 11811 >"$dir/server.log" 2>&1 &
  pids+=($!)
  sleep 1
fi
case $flood_target in
  multicast) target=() ;;
  server) target=(--target 127.0.0.1:11811) ;;
  bridge) target=() ;;  # its port once it runs (below)
  *) echo "plant-scale.sh: --flood-target multicast, server or bridge" >&2; exit 2 ;;
esac
cat >"$dir/plain.yaml" <<EOF
line: plant
dds: {domain: $domain$ds_keys}
buses:
  - {name: b, interface: 'virtual:plant-$$', sync_period_ms: 20}
devices:
$devices
EOF
line=$dir/plain.yaml
ident=()
client_id=()
flood_id=()
if ((secured)); then
  launch_scripts/pki.sh init --config "$dir/plain.yaml" --dir "$dir/pki" >"$dir/pki-init.out" 2>"$dir/pki.log"
  for ((i = 0; i < identities; i++)); do
    launch_scripts/pki.sh issue --config "$dir/plain.yaml" --dir "$dir/pki" --name "hmi$i" --role observer >>"$dir/pki.log" 2>&1
    ident+=(--identity "$dir/pki/hmi$i")
  done
  launch_scripts/pki.sh issue --config "$dir/plain.yaml" --dir "$dir/pki" --name client --role engineer >>"$dir/pki.log" 2>&1
  launch_scripts/pki.sh issue --config "$dir/plain.yaml" --dir "$dir/pki" --name replayed --role observer >>"$dir/pki.log" 2>&1
  client_id=(--identity "$dir/pki/client")
  flood_id=(--pki "$dir/pki" --identity replayed)
  {
    echo "line: plant"
    echo "dds:"
    echo "  domain: $domain"
    sed -n '/^  security:/,/^[^ ]/p' "$dir/pki-init.out" | grep '^  '
    echo "buses:"
    echo "  - {name: b, interface: 'virtual:plant-$$', sync_period_ms: 20}"
    echo "devices:"
    echo "$devices"
  } >"$dir/line.yaml"
  line=$dir/line.yaml
fi
grep -q "security:" "$line" || ((!secured)) || { echo "plant-scale.sh: no dds.security block made" >&2; cat "$dir/pki.log" >&2; exit 1; }

"$bin/linebridge-sim" --config "$line" >"$dir/sim.log" 2>&1 &
pids+=($!)
"$bin/linebridge" --config "$line" >"$dir/bridge.log" 2>&1 &
bridge=$!
pids+=($bridge)
for _ in $(seq 300); do grep -q "DDS side of line plant ready" "$dir/bridge.log" && break; sleep 0.1; done
grep -q "DDS side of line plant ready" "$dir/bridge.log" || { echo "plant-scale.sh: the bridge never got ready" >&2; cat "$dir/bridge.log" >&2; exit 1; }
mark "bridge ready (domain $domain, $([ "$secured" = 1 ] && echo secured || echo unsecured)$([ "$discovery_server" = 1 ] && echo ", discovery server"))"

# The long-running clients, before anything else.
"$bin/linebridge-cli" --config "$line" "${client_id[@]}" echo saw1 status --rate 20 2>"$dir/echo.err" |
  while IFS= read -r l; do echo "${EPOCHREALTIME} $l"; done >"$dir/echo.out" &
pids+=($!)
"$bench/bench-plant-participants" --config "$line" "${client_id[@]}" --participants 1 --service-every-ms 1000 --fastdds-log \
  --duration 100000 --every 5 >"$dir/client.out" 2>"$dir/client.err" &
pids+=($!)
sleep 5

dds_pid() { cat "/proc/$bridge/task/"*/children 2>/dev/null | tr ' ' '\n' | grep -m1 . || true; }
restarts() { grep -c "a new DDS process starts" "$dir/bridge.log" || true; }
# Every second: the DDS process's pid, resident KiB and CPU ticks (utime + stime).
(
  while kill -0 "$bridge" 2>/dev/null; do
    p=$(dds_pid)
    if [ -n "$p" ] && [ -r "/proc/$p/stat" ]; then
      rss=$(awk '/^VmRSS/ { print $2 }' "/proc/$p/status" 2>/dev/null || echo 0)
      ticks=$(awk '{ print $14 + $15 }' "/proc/$p/stat" 2>/dev/null || echo 0)
      echo "$(now) $p ${rss:-0} ${ticks:-0}"
    fi
    sleep 1
  done
) >"$dir/dds.samples" &
pids+=($!)

echo "readers=$readers bystanders=$bystanders honest_s=$honest_s flood_s=$flood_s after_s=$after_s lease_s=$lease_s repeat=$repeat secured=$secured discovery_server=$discovery_server flood_target=$flood_target" >"$dir/params"
mark "honest crowd: $readers readers, $bystanders bystanders"
"$bench/bench-plant-participants" --config "$line" "${ident[@]}" --participants "$readers" --bystanders "$bystanders" \
  --duration "$honest_s" --every 5 >"$dir/crowd.out" 2>"$dir/crowd.err" || echo "plant-scale.sh: the crowd failed: $(tail -3 "$dir/crowd.err")"
mark "honest crowd done"
grep -E "^(created|at=|readers)" "$dir/crowd.out" | sed 's/^/  crowd: /'

for rate in $rates; do
  sleep 10
  count=$(awk -v r="$rate" -v s="$flood_s" 'BEGIN { printf "%d", r * s }')
  if [ "$flood_target" = bridge ]; then
    # The DDS process's discovery (metatraffic) unicast port: 7410 + 250 x domain + 2 x its participant id.
    port=$(python3 - "$(dds_pid)" "$domain" <<'PY'
import os, sys
pid, domain = sys.argv[1], int(sys.argv[2])
inodes = {os.readlink("/proc/%s/fd/%s" % (pid, f))[8:-1] for f in os.listdir("/proc/%s/fd" % pid)
          if os.readlink("/proc/%s/fd/%s" % (pid, f)).startswith("socket:")}
base = 7410 + 250 * domain
for line in open("/proc/net/udp").readlines()[1:]:
    f = line.split()
    port = int(f[1].split(":")[1], 16)
    if f[9] in inodes and port >= base and (port - base) % 2 == 0 and port - base < 240:
        print(port)
        break
PY
)
    target=(--target "127.0.0.1:$port")
  fi
  mark "flood at $rate/s for $flood_s s (lease $lease_s s, each sent $repeat time(s), to the $flood_target${target[1]:+ ${target[1]}})"
  "$bench/bench-forged-announcements" --domain "$domain" "${flood_id[@]}" "${target[@]}" --count "$count" --rate "$rate" \
    --lease-s "$lease_s" --repeat "$repeat" >"$dir/flood_$rate.out" 2>&1 || echo "plant-scale.sh: the flood tool failed: $(tail -2 "$dir/flood_$rate.out")"
  mark "flood at $rate/s ended ($(grep -h datagrams_sent "$dir/flood_$rate.out"))"
  sleep "$after_s"
done
mark "end"
report "$dir"
