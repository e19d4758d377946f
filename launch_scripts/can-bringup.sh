#!/usr/bin/env bash
# Configures a real CAN interface for a line and brings it up: bit rate, automatic restart after
# bus-off (restart-ms) and the transmit queue length. Idempotent: an interface that is already up
# with these settings is left alone (no bus interruption); otherwise it is taken down, set, and
# brought up again. Run as root (the systemd unit runs it before the gateway starts).
#   launch_scripts/can-bringup.sh IFNAME [--bitrate BPS] [--restart-ms MS] [--txqueuelen N] [--dry-run]
#     --bitrate     bit/s, default 500000 (CiA 420 lines use 125000..500000; all nodes must agree)
#     --restart-ms  ms after bus-off before the controller restarts by itself, default 100
#                   (0 = stay bus-off until `ip link set IFNAME type can restart`)
#     --txqueuelen  frames the kernel queues before send() fails with ENOBUFS, default 1000
#                   (the driver default of 10 overflows on a burst of SDO or PDO frames)
#     --dry-run     print the ip commands instead of running them
# Exit status: 0 configured (or already so), 1 the interface is missing or ip refused, 2 usage.
set -euo pipefail

usage() { sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; }
[ $# -ge 1 ] || { usage >&2; exit 2; }
case "$1" in -h|--help) usage; exit 0 ;; -*) usage >&2; exit 2 ;; esac
ifname=$1
shift
bitrate=500000
restart_ms=100
txqueuelen=1000
dry=0
while [ $# -gt 0 ]; do
  case "$1" in
    --bitrate) bitrate=${2:?}; shift 2 ;;
    --restart-ms) restart_ms=${2:?}; shift 2 ;;
    --txqueuelen) txqueuelen=${2:?}; shift 2 ;;
    --dry-run) dry=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "can-bringup: unknown argument $1" >&2; exit 2 ;;
  esac
done
for n in "$bitrate" "$restart_ms" "$txqueuelen"; do
  [[ "$n" =~ ^[0-9]+$ ]] || { echo "can-bringup: '$n' is not a number" >&2; exit 2; }
done
((bitrate >= 10000 && bitrate <= 1000000)) || { echo "can-bringup: bit rate $bitrate outside 10000..1000000" >&2; exit 2; }

run() {
  if [ "$dry" = 1 ]; then echo "$*"; else "$@"; fi
}

details=$(ip -details link show dev "$ifname" 2>/dev/null) || {
  echo "can-bringup: no interface $ifname (is the CAN adapter's driver loaded? ip link shows what exists)" >&2
  exit 1
}
grep -q 'link/can' <<<"$details" || { echo "can-bringup: $ifname is not a CAN interface" >&2; exit 1; }

# vcan has no bit timing: only the queue length and the link state apply.
if grep -qw vcan <<<"$details"; then
  grep -q "qlen $txqueuelen\b" <<<"$details" || run ip link set dev "$ifname" txqueuelen "$txqueuelen"
  run ip link set dev "$ifname" up
  echo "can-bringup: $ifname (vcan) up, txqueuelen $txqueuelen"
  exit 0
fi

if grep -q '<.*\bUP\b.*>' <<<"$details" &&
  grep -q "bitrate $bitrate\b" <<<"$details" &&
  grep -q "restart-ms $restart_ms\b" <<<"$details" &&
  grep -q "qlen $txqueuelen\b" <<<"$details"; then
  echo "can-bringup: $ifname already up at $bitrate bit/s, restart-ms $restart_ms, txqueuelen $txqueuelen"
  exit 0
fi

run ip link set dev "$ifname" down
run ip link set dev "$ifname" type can bitrate "$bitrate" restart-ms "$restart_ms"
run ip link set dev "$ifname" txqueuelen "$txqueuelen"
run ip link set dev "$ifname" up
echo "can-bringup: $ifname up at $bitrate bit/s, restart-ms $restart_ms, txqueuelen $txqueuelen"
