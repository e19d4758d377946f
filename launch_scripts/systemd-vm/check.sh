#!/bin/bash
# The check that launch_scripts/systemd-vm.sh runs inside the guest (systemd as PID 1), started by
# linebridge-vm-check.service once multi-user.target is reached. It drives the package's real units
# on a vcan bus and writes its results to the job share (/lbjob): check.log (this output), rc (0
# all checks passed, 1 a check failed, 2 the check could not run), summary.txt, journal.txt,
# candump.log. Never run on the host.
#
# Parameters (/lbjob/check.conf, written by systemd-vm.sh):
#   UNITS        the units under test, in start order (e.g. "linebridge-bus.service
#                linebridge-dds.service"; today "linebridge.service")
#   BUS_UNIT     the unit that sends SYNC on vcan0; killing any *other* unit must leave its MainPID
#                and its SYNC untouched (no gap > GAP_PERIODS SYNC periods)
#   MARGIN_S     slack on top of WatchdogSec + RestartSec for a restart to complete (TCG is slow)
#   GAP_PERIODS  largest SYNC gap allowed while a non-bus unit is killed, in SYNC periods
#   SIM          1: run linebridge-sim for the line's devices (a transient unit) so the line boots
set -uo pipefail
job=/lbjob
# shellcheck source=/dev/null
. "$job/check.conf"
exec > >(tee "$job/check.log") 2>&1
tee_pid=$!

failures=0
summary=()
t_boot=$(date +%s.%N)
now() { date +%s.%N; }
fmt() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }
say() { echo "[$(fmt "$t_boot" "$(now)") s] $*"; }
pass() { say "PASS $*"; summary+=("PASS $*"); }
failed() { say "FAIL $*"; summary+=("FAIL $*"); failures=$((failures + 1)); }
info() { say "     $*"; summary+=("     $*"); }
prop() { systemctl show -P "$2" "$1"; }
# A systemd time span property (e.g. "10s", "2s", "infinity") in seconds.
span_s() {
  local v
  v=$(prop "$1" "$2")
  case "$v" in
    ''|0|infinity) echo 0 ;;
    *) systemd-analyze timespan "$v" | awk '/μs:/ { printf "%.3f", $2 / 1e6 }' ;;
  esac
}

finish() {
  local rc=$1
  {
    echo "== summary (units: $UNITS; bus unit: $BUS_UNIT)"
    printf '%s\n' "${summary[@]}"
  } >"$job/summary.txt"
  journalctl -b -o short-unix --no-pager >"$job/journal.txt" 2>&1
  [ -n "${dump_pid:-}" ] && kill "$dump_pid" 2>/dev/null
  cp /run/lbvm/candump.log "$job/candump.log" 2>/dev/null
  # Everything tee has is in check.log before the result says the check is over.
  exec >&- 2>&-
  wait "$tee_pid" 2>/dev/null
  echo "$rc" >"$job/rc.tmp" && mv "$job/rc.tmp" "$job/rc"
  sync
  exit 0
}

# SYNC frames (0x080) on vcan0 between two times: "count max_gap_ms mean_period_ms span_s".
sync_stats() {
  awk -v a="$1" -v b="$2" '
    $3 == "080" { t = substr($1, 2, length($1) - 2) + 0
                  if (t < a || t > b) next
                  if (n) { g = (t - p) * 1000; if (g > max) max = g }
                  if (!n) first = t
                  p = t; n++ }
    END { if (n > 1) printf "%d %.1f %.2f %.2f\n", n, max, (p - first) * 1000 / (n - 1), p - first
          else printf "%d 0 0 0\n", n }' /run/lbvm/candump.log
}
# Waits (up to $3 s) for a SYNC frame stamped after $1; prints its stamp or nothing.
first_sync_after() {
  local deadline
  deadline=$(awk -v s="$(now)" -v d="$2" 'BEGIN { printf "%.3f", s + d }')
  while :; do
    t=$(awk -v a="$1" '$3 == "080" { t = substr($1, 2, length($1) - 2) + 0; if (t > a) { printf "%.6f\n", t; exit } }' /run/lbvm/candump.log)
    [ -n "$t" ] && { echo "$t"; return 0; }
    awk -v n="$(now)" -v d="$deadline" 'BEGIN { exit !(n > d) }' && return 1
    sleep 0.1
  done
}
# True when node $1's heartbeat says operational (0x05) in a frame stamped after $2.
operational_after() {
  local id
  id=$(printf '%03X' $((0x700 + $1)))
  awk -v a="$2" -v id="$id" '$3 == id && $5 == "05" { t = substr($1, 2, length($1) - 2) + 0; if (t > a) { f = 1; exit } }
                             END { exit !f }' /run/lbvm/candump.log
}
wait_operational() {
  local node=$1 after=$2 limit=$3 i
  for ((i = 0; i < limit * 10; i++)); do
    operational_after "$node" "$after" && return 0
    sleep 0.1
  done
  return 1
}
# Waits for unit $1 to be active with a main PID other than $2; prints the time it was seen.
wait_restarted() {
  local u=$1 old=$2 limit=$3 deadline pid st
  deadline=$(awk -v s="$(now)" -v d="$limit" 'BEGIN { printf "%.3f", s + d }')
  while :; do
    pid=$(prop "$u" MainPID)
    st=$(prop "$u" ActiveState)
    if [ "$st" = active ] && [ "$pid" != 0 ] && [ "$pid" != "$old" ]; then now; return 0; fi
    awk -v n="$(now)" -v d="$deadline" 'BEGIN { exit !(n > d) }' && return 1
    sleep 0.1
  done
}
journal_since() { journalctl -u "$1" --since "@${2%.*}" -o short-unix --no-pager 2>/dev/null; }

# --- set-up: vcan0, the line file on it, the unit's settings ------------------------------------
mkdir -p /run/lbvm
say "kernel $(uname -r), systemd $(systemctl --version | awk 'NR == 1 { print $2 }'), PID 1: $(cat /proc/1/comm)"
[ "$(cat /proc/1/comm)" = systemd ] || { failed "PID 1 is not systemd"; finish 2; }
if ! { ip link add dev vcan0 type vcan && ip link set vcan0 up; }; then failed "cannot create vcan0"; finish 2; fi
line=/etc/linebridge/vm-line.yaml
# The package's own example line file, its bus moved to vcan0 (CAN_IF empty: no bring-up of a
# real adapter; a vcan needs none).
sed 's#interface: socketcan:can0#interface: socketcan:vcan0#' /etc/linebridge/line.yaml >"$line"
grep -q 'socketcan:vcan0' "$line" || { failed "the package's line.yaml has no socketcan:can0 bus to move"; finish 2; }
chgrp linebridge "$line" && chmod 0640 "$line"
period_ms=$(awk '/sync_period_ms:/ { print $2; exit }' "$line")
node=$(awk '$1 == "node_id:" { print $2; exit }' "$line")
cat >/etc/default/linebridge <<CONF
CAN_IF=
LINEBRIDGE_CONFIG=$line
LINEBRIDGE_LOG_LEVEL=info
CONF
info "line file: /etc/linebridge/line.yaml on vcan0, SYNC period ${period_ms} ms, device node $node"
if ! /usr/bin/linebridge --check "$line" >/run/lbvm/check-config.log 2>&1; then
  cat /run/lbvm/check-config.log
  failed "linebridge --check $line"
  finish 1
fi

stdbuf -oL candump -t a vcan0,080:7FF,700:780 >/run/lbvm/candump.log 2>/run/lbvm/candump.err &
dump_pid=$!
sleep 0.5
if [ "${SIM:-1}" = 1 ]; then
  systemd-run --quiet --unit=linebridge-vm-sim /usr/bin/linebridge-sim --config "$line" ||
    { failed "cannot start linebridge-sim"; finish 2; }
fi

# --- 1. start: Type=notify, READY, SYNC on vcan0, device operational ------------------------------
for u in $UNITS; do
  t0=$(now)
  if ! timeout 120 systemctl start "$u"; then
    systemctl status --no-pager -l "$u"
    failed "$u: systemctl start"
    finish 1
  fi
  t1=$(now)
  st="$(prop "$u" Type)/$(prop "$u" ActiveState)/$(prop "$u" SubState)"
  if [ "$st" = notify/active/running ]; then
    pass "$u: started, READY=1 after $(fmt "$t0" "$t1") s (Type/ActiveState/SubState $st)"
  else
    failed "$u: after start: $st (want notify/active/running)"
  fi
  info "$u: MainPID=$(prop "$u" MainPID) NotifyAccess=$(prop "$u" NotifyAccess) WatchdogUSec=$(prop "$u" WatchdogUSec) Restart=$(prop "$u" Restart) RestartUSec=$(prop "$u" RestartUSec) User=$(prop "$u" User)"
done
if s=$(first_sync_after "$t0" 10); then
  sleep 3
  read -r n gap mean span <<<"$(sync_stats "$s" "$(now)")"
  if [ "$n" -ge 10 ]; then
    pass "SYNC on vcan0 (candump -t a): first $(fmt "$t0" "$s") s after the start command; then $n frames in $span s, mean period $mean ms (configured $period_ms), largest gap $gap ms"
  else
    failed "SYNC on vcan0: only $n frames in $span s"
  fi
else
  failed "no SYNC frame on vcan0 within 10 s of the start"
fi
if [ "${SIM:-1}" = 1 ]; then
  if wait_operational "$node" "$t0" 30; then
    pass "device node $node operational on vcan0 (heartbeat 0x$(printf '%03X' $((0x700 + node))) = 05)"
  else
    failed "device node $node not operational within 30 s"
  fi
fi

# --- 2./3. kill -9 and SIGSTOP (watchdog) of each unit's main process -----------------------------
# One event: $1 unit, $2 signal (KILL or STOP).
event() {
  local u=$1 sig=$2 pid n0 wd rs limit t_ev t_back t_wd t_exit exitline o opid ok=1
  pid=$(prop "$u" MainPID)
  n0=$(prop "$u" NRestarts)
  wd=$(span_s "$u" WatchdogUSec)
  rs=$(span_s "$u" RestartUSec)
  declare -A others
  for o in $UNITS; do [ "$o" = "$u" ] || others[$o]=$(prop "$o" MainPID); done
  if [ "$sig" = STOP ]; then
    [ "${wd%.*}" -gt 0 ] || { failed "$u: no WatchdogSec: nothing to stall"; return; }
    limit=$(awk -v w="$wd" -v r="$rs" -v m="$MARGIN_S" 'BEGIN { print w + r + m }')
  else
    limit=$(awk -v r="$rs" -v m="$MARGIN_S" 'BEGIN { print r + m }')
  fi
  say "$u: kill -$sig $pid (NRestarts $n0; restart expected within $limit s)"
  t_ev=$(now)
  kill "-$sig" "$pid"
  if ! t_back=$(wait_restarted "$u" "$pid" "$limit"); then
    failed "$u after kill -$sig: not active with a new main PID within $limit s (state $(prop "$u" ActiveState)/$(prop "$u" SubState), MainPID $(prop "$u" MainPID))"
    journal_since "$u" "$t_ev" | tail -n 20
    [ "$sig" = STOP ] && kill -CONT "$pid" 2>/dev/null
    return
  fi
  local n1 pid1
  n1=$(prop "$u" NRestarts)
  pid1=$(prop "$u" MainPID)
  sleep 0.5
  local j
  j=$(journal_since "$u" "$t_ev")
  exitline=$(grep -m1 'Main process exited' <<<"$j" | sed 's/^[0-9.]* [^ ]* //')
  t_exit=$(grep -m1 'Main process exited' <<<"$j" | awk '{ print $1 }')
  [ "$n1" = $((n0 + 1)) ] || { ok=0; failed "$u after kill -$sig: NRestarts $n0 -> $n1 (want +1)"; }
  if [ "$sig" = STOP ]; then
    t_wd=$(grep -m1 'Watchdog timeout' <<<"$j" | awk '{ print $1 }')
    if [ -z "$t_wd" ]; then
      ok=0; failed "$u after kill -STOP: no 'Watchdog timeout' in the journal"
    else
      local d
      d=$(fmt "$t_ev" "$t_wd")
      # The service pings at least every WatchdogSec/2, so the timeout falls between W/2 and W
      # after the stall (plus the journal's and TCG's slack).
      if awk -v d="$d" -v w="$wd" 'BEGIN { exit !(d >= w / 2 - 1 && d <= w + 1.5) }'; then
        info "$u: journal: watchdog timeout $d s after the stall (WatchdogSec ${wd}s)"
      else
        ok=0; failed "$u: watchdog timeout $d s after the stall, outside [W/2 - 1, W + 1.5] (W = ${wd}s)"
      fi
    fi
    grep -q "Failed with result 'watchdog'" <<<"$j" || { ok=0; failed "$u after kill -STOP: no \"Failed with result 'watchdog'\" in the journal"; }
    grep -Eq 'status=(6/ABRT|9/KILL)' <<<"$exitline" || { ok=0; failed "$u after kill -STOP: exit '$exitline' (want SIGABRT, or SIGKILL after TimeoutAbortSec)"; }
  else
    grep -q 'status=9/KILL' <<<"$exitline" || { ok=0; failed "$u after kill -9: exit '$exitline' (want status=9/KILL)"; }
  fi
  info "$u: journal: $exitline"
  [ "$ok" = 1 ] && pass "$u: kill -$sig of main PID $pid: restarted by systemd, main PID $pid -> $pid1, NRestarts $n0 -> $n1, active again $(fmt "$t_ev" "$t_back") s after the signal (limit $limit s; exit seen at +$(fmt "$t_ev" "${t_exit:-$t_ev}") s)"
  # The other units: same main process, and when the bus unit is one of them, SYNC without a gap.
  for o in "${!others[@]}"; do
    opid=$(prop "$o" MainPID)
    if [ "$opid" = "${others[$o]}" ]; then
      pass "$o: main PID $opid unchanged while $u was killed"
    elif [ "$u" = "$BUS_UNIT" ]; then
      # The DDS process ends with its bus process (it has nothing to serve) and systemd starts it
      # again: expected, and it must be running again (checked at the end).
      info "$o: main PID ${others[$o]} -> $opid after the bus unit $u was killed (the DDS side ends with its bus side)"
    else
      failed "$o: main PID ${others[$o]} -> $opid while $u was killed"
    fi
  done
  local s n gap mean span
  s=$(first_sync_after "$t_back" 15) || { failed "no SYNC on vcan0 within 15 s after $u came back"; return; }
  sleep 1
  read -r n gap mean span <<<"$(sync_stats "$(awk -v t="$t_ev" 'BEGIN { printf "%.6f", t - 1 }')" "$(now)")"
  if [ "$u" = "$BUS_UNIT" ]; then
    info "$u is the bus unit: SYNC outage (largest gap, $n frames in $span s) ${gap} ms, SYNC again $(fmt "$t_ev" "$s") s after the signal"
  else
    local allowed=$((GAP_PERIODS * period_ms))
    if awk -v g="$gap" -v a="$allowed" 'BEGIN { exit !(g <= a) }'; then
      pass "SYNC on vcan0 while $u was killed: largest gap $gap ms <= $GAP_PERIODS periods ($allowed ms), $n frames in $span s"
    else
      failed "SYNC on vcan0 while $u was killed: largest gap $gap ms > $GAP_PERIODS periods ($allowed ms)"
    fi
  fi
  if [ "${SIM:-1}" = 1 ]; then
    if wait_operational "$node" "$t_back" 30; then
      info "device node $node operational again after $u came back"
    else
      failed "device node $node not operational within 30 s after $u came back"
    fi
  fi
}

# The units in reverse start order: the DDS side first, the bus side last.
rev=$(echo "$UNITS" | tr ' ' '\n' | tac | tr '\n' ' ')
for u in $rev; do event "$u" KILL; done
for u in $rev; do event "$u" STOP; done

# --- the end state ------------------------------------------------------------------------------
for u in $UNITS; do
  st="$(prop "$u" ActiveState)/$(prop "$u" SubState)"
  if [ "$st" = active/running ]; then
    pass "$u: $st at the end, NRestarts $(prop "$u" NRestarts)"
  else
    failed "$u: $st at the end"
  fi
done
info "candump: $(grep -c ' 080 ' /run/lbvm/candump.log) SYNC frames in all"
say "done: $failures check(s) failed"
[ "$failures" = 0 ] && finish 0
finish 1
