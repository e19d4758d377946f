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
#   SUSTAIN_S    seconds of a DDS process killed again and again (kill -9 of the DDS unit's main
#                process each time it is active, after 0-0.5 s): the DDS unit keeps coming back,
#                the bus unit's main PID never changes, SYNC never gaps over SUSTAIN_GAP_PERIODS
#                (0: no such phase)
#   SUSTAIN_GAP_PERIODS  largest SYNC gap allowed in that phase, in SYNC periods
#   ALARM_S      the bus unit's LINEBRIDGE_DDS_ABSENT_ALARM_S here (its alarm without a DDS side)
#   TAKEOVER     1: instead of all of the above, the hot standby scenario of takeover.sh (a step
#                back and two takeovers with the units; its own parameters are listed there)
# The key events' journal entries (docs/operations.md, "Searching the journal"): with SIM, the
# simulator killed and started again must give the device's device_lost and device_online entries
# (journalctl MESSAGE_ID=... LB_DEVICE=...) with its line, bus and node; the DDS unit's process
# killed, the bus unit's dds_side_gone and dds_side_back entries with the old and new PIDs.
set -uo pipefail
job=/lbjob
# shellcheck source=/dev/null
. "$job/check.conf"
SUSTAIN_S=${SUSTAIN_S:-0}
SUSTAIN_GAP_PERIODS=${SUSTAIN_GAP_PERIODS:-2}
ALARM_S=${ALARM_S:-5}
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
# How many SYNC gaps between two times are wider than $3 ms.
gaps_over() {
  awk -v a="$1" -v b="$2" -v lim="$3" '
    $3 == "080" { t = substr($1, 2, length($1) - 2) + 0
                  if (t < a || t > b) next
                  if (n && (t - p) * 1000 > lim) c++
                  p = t; n++ }
    END { print c + 0 }' /run/lbvm/candump.log
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
# The key events' MESSAGE_IDs, as docs/operations.md lists them (never change).
ID_DEVICE_ONLINE=fecb2be038e74664b679c1f1ed7526f6
ID_DEVICE_LOST=6279545544e24482b4b2b0a619f497d2
ID_DDS_SIDE_GONE=3da26d56a43344538469b32eaa7a10fb
ID_DDS_SIDE_BACK=ed00515540b8490389079f63dd96153f
# Waits up to $3 s for the journal's entries of MESSAGE_ID $1 since $2 that match the fields
# given after (NAME=value, journalctl's matches); prints the first (-o verbose).
journal_event() {
  local id=$1 since=$2 limit=$3 i out
  shift 3
  for ((i = 0; i < limit * 5; i++)); do
    out=$(journalctl MESSAGE_ID="$id" "$@" --since "@${since%.*}" -o verbose --no-pager --quiet 2>/dev/null |
      awk 'NR > 1 && /^[^ ]/ { exit } { print }')
    grep -q "^ *MESSAGE_ID=$id\$" <<<"$out" && { echo "$out"; return 0; }
    sleep 0.2
  done
  return 1
}
# A field of an entry journal_event printed.
entry_field() { sed -n "s/^ *$1=//p" <<<"$2" | head -n 1; }
# Checks an entry journal_event printed: each NAME=value given after it; prints what differs.
entry_differs() {
  local entry=$1 f
  shift
  for f in "$@"; do
    [ "$(entry_field "${f%%=*}" "$entry")" = "${f#*=}" ] || echo -n "${f%%=*}=$(entry_field "${f%%=*}" "$entry") (want ${f#*=}); "
  done
}
# One key event's journal entry: waits up to LIMIT s since SINCE for MESSAGE_ID ID matching the
# fields before "--" (journalctl's matches), then checks the entry's fields after "--" (NAME=value).
#   check_journal_entry EVENT ID SINCE LIMIT MATCH... -- WANT...
check_journal_entry() {
  local event=$1 id=$2 since=$3 limit=$4 e bad
  shift 4
  local match=()
  while [ $# -gt 0 ] && [ "$1" != -- ]; do match+=("$1"); shift; done
  shift
  if e=$(journal_event "$id" "$since" "$limit" "${match[@]}"); then
    bad=$(entry_differs "$e" LB_EVENT="$event" "$@")
    if [ -z "$bad" ]; then
      pass "journal: journalctl MESSAGE_ID=$id ${match[*]} ($event $*): $(entry_field MESSAGE "$e")"
    else
      failed "journal: the $event entry (${match[*]}): $bad"
    fi
  else
    failed "journal: no entry MESSAGE_ID=$id ${match[*]} ($event) within $limit s"
    journalctl MESSAGE_ID="$id" -o verbose --no-pager | tail -n 30
  fi
}
# The bus unit's dds_side_gone (DDS process $2) and dds_side_back (DDS process $3) entries since $1.
check_dds_side_entries() {
  check_journal_entry dds_side_gone "$ID_DDS_SIDE_GONE" "$1" 30 LB_LINE="$line_name" LB_DDS_PID="$2" -- \
    PRIORITY=4 _SYSTEMD_UNIT="$BUS_UNIT"
  check_journal_entry dds_side_back "$ID_DDS_SIDE_BACK" "$1" 60 LB_LINE="$line_name" LB_DDS_PID="$3" -- \
    PRIORITY=6 _SYSTEMD_UNIT="$BUS_UNIT"
}
# The line file the package's units run: readable by their group, named in their environment; its
# SYNC period and its first device's node-ID into period_ms and node.
use_line() {
  chgrp linebridge "$1" && chmod 0640 "$1"
  period_ms=$(awk '/sync_period_ms:/ { print $2; exit }' "$1")
  node=$(awk '$1 == "node_id:" { print $2; exit }' "$1")
  # The names the key events carry (LB_LINE, LB_BUS, LB_DEVICE): the line's, its first bus's and device's.
  line_name=$(awk '$1 == "line:" { print $2; exit }' "$1")
  bus_name=$(awk '/^buses:/ { b = 1 } b && $1 == "-" && $2 == "name:" { print $3; exit }' "$1")
  device=$(awk '/^devices:/ { d = 1 } d && $1 == "-" && $2 == "name:" { print $3; exit }' "$1")
  cat >/etc/default/linebridge <<CONF
CAN_IF=
LINEBRIDGE_CONFIG=$1
LINEBRIDGE_LOG_LEVEL=info
LINEBRIDGE_DDS_ABSENT_ALARM_S=$ALARM_S
CONF
}

# --- set-up: vcan0, the line file on it, the unit's settings ------------------------------------
mkdir -p /run/lbvm
say "kernel $(uname -r), systemd $(systemctl --version | awk 'NR == 1 { print $2 }'), PID 1: $(cat /proc/1/comm)"
[ "$(cat /proc/1/comm)" = systemd ] || { failed "PID 1 is not systemd"; finish 2; }
if ! { ip link add dev vcan0 type vcan && ip link set vcan0 up; }; then failed "cannot create vcan0"; finish 2; fi
# --takeover: the hot standby scenario instead of the checks below (it ends with finish).
# shellcheck source=takeover.sh disable=SC1091
[ "${TAKEOVER:-0}" = 1 ] && . "$(dirname "$0")/takeover.sh"
line=/etc/linebridge/vm-line.yaml
# The package's own example line file, its bus moved to vcan0 (CAN_IF empty: no bring-up of a
# real adapter; a vcan needs none).
sed 's#interface: socketcan:can0#interface: socketcan:vcan0#' /etc/linebridge/line.yaml >"$line"
grep -q 'socketcan:vcan0' "$line" || { failed "the package's line.yaml has no socketcan:can0 bus to move"; finish 2; }
use_line "$line"
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

# --- 1b. the device's key events in the journal: its simulator killed, then started again -------
if [ "${SIM:-1}" = 1 ]; then
  t_sim=$(now)
  say "linebridge-vm-sim: kill -9 (device $device, node $node: lost after its heartbeat timeout)"
  systemctl kill -s KILL linebridge-vm-sim.service
  check_journal_entry device_lost "$ID_DEVICE_LOST" "$t_sim" 30 LB_DEVICE="$device" -- LB_LINE="$line_name" \
    LB_BUS="$bus_name" LB_NODE="$node" PRIORITY=4 _SYSTEMD_UNIT="$BUS_UNIT"
  systemctl reset-failed linebridge-vm-sim.service 2>/dev/null
  t_sim=$(now)
  if systemd-run --quiet --unit=linebridge-vm-sim /usr/bin/linebridge-sim --config "$line"; then
    check_journal_entry device_online "$ID_DEVICE_ONLINE" "$t_sim" 30 LB_DEVICE="$device" -- LB_LINE="$line_name" \
      LB_BUS="$bus_name" LB_NODE="$node" PRIORITY=6 _SYSTEMD_UNIT="$BUS_UNIT"
    if wait_operational "$node" "$t_sim" 30; then
      info "device node $node operational again after its simulator came back"
    else
      failed "device node $node not operational within 30 s after its simulator came back"
    fi
  else
    failed "cannot start linebridge-sim again"
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
  # The DDS unit's process killed: the bus process's key events say so, with both processes.
  [ "$u" != "$BUS_UNIT" ] && [ "$sig" = KILL ] && check_dds_side_entries "$t_ev" "$pid" "$pid1"
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

# --- 4. the DDS side as its own user; only it on the channel; it cannot signal the bus process ----
# The units of a line: the bus unit and the other one (the DDS unit).
dds_unit=""
for u in $UNITS; do [ "$u" = "$BUS_UNIT" ] || dds_unit=$u; done
bus_journal_since() { journal_since "$BUS_UNIT" "$1"; }
# Waits until the DDS unit is active and the bus unit's journal says its main process connected.
dds_connected() {
  local limit=$1 i pid
  for ((i = 0; i < limit * 10; i++)); do
    pid=$(prop "$dds_unit" MainPID)
    if [ "$(prop "$dds_unit" ActiveState)" = active ] && [ "$pid" != 0 ] &&
        journalctl -u "$BUS_UNIT" -o cat --no-pager | grep -q "DDS side connected (pid $pid[,)]"; then
      echo "$pid"; return 0
    fi
    sleep 0.1
  done
  return 1
}
if [ -n "$dds_unit" ]; then
  bus_user=$(prop "$BUS_UNIT" User)
  dds_user=$(prop "$dds_unit" User)
  bus_pid=$(prop "$BUS_UNIT" MainPID)
  if ! dds_pid=$(dds_connected 60); then
    failed "$dds_unit: not connected to the bus process within 60 s"
  else
    bus_uid=$(ps -o uid= -p "$bus_pid" | tr -d ' ')
    dds_uid=$(ps -o uid= -p "$dds_pid" | tr -d ' ')
    if [ "$bus_uid" != "$dds_uid" ]; then
      pass "users: $BUS_UNIT runs as $bus_user (uid $bus_uid), $dds_unit as $dds_user (uid $dds_uid, groups $(ps -o supgrp= -p "$dds_pid" | tr -d ' '))"
    else
      failed "users: $BUS_UNIT and $dds_unit both run as uid $bus_uid"
    fi
    # A process of the DDS unit's user with what of the unit's settings bears on signals: its
    # user and groups, no capability, no new privileges. (The seccomp filter is not replayed:
    # @system-service allows kill either way.)
    dds_groups=$(prop "$dds_unit" SupplementaryGroups | tr ' ' ',')
    groups_opt=(--clear-groups)
    [ -n "$dds_groups" ] && groups_opt=(--groups="$dds_groups")
    t_sig=$(now)
    for sig in STOP KILL; do
      out=$(setpriv --reuid="$dds_user" --regid="$(prop "$dds_unit" Group)" "${groups_opt[@]}" --inh-caps=-all \
        --bounding-set=-all --no-new-privs /bin/kill -s "$sig" "$bus_pid" 2>&1)
      rc=$?
      sleep 0.5
      state=$(awk '{ print $3 }' "/proc/$bus_pid/stat" 2>/dev/null)
      if [ "$rc" != 0 ] && grep -q 'not permitted' <<<"$out" && [ "$state" != T ] &&
          [ "$(prop "$BUS_UNIT" MainPID)" = "$bus_pid" ]; then
        pass "signal: kill -$sig of the bus process ($bus_pid) by $dds_user (groups ${dds_groups:-none}, no capability) refused: $(tail -n 1 <<<"$out"); it runs on (state $state)"
      else
        failed "signal: kill -$sig of the bus process ($bus_pid) by $dds_user: exit $rc '$(tail -n 1 <<<"$out")', bus process state '${state:-gone}', MainPID now $(prop "$BUS_UNIT" MainPID)"
        kill -CONT "$bus_pid" 2>/dev/null
      fi
    done
    sleep 1
    read -r n gap mean span <<<"$(sync_stats "$t_sig" "$(now)")"
    info "SYNC while the DDS user signalled: $n frames in $span s, largest gap $gap ms"
    # Connections to the channel: a user whose primary group is the bus unit's, then a second
    # process of the DDS unit's user while its DDS side is connected. Each runs linebridge --part
    # dds as the DDS side would.
    id lbvm-intruder >/dev/null 2>&1 || useradd --system --no-create-home --shell /usr/sbin/nologin \
      --gid "$(prop "$BUS_UNIT" Group)" lbvm-intruder
    attempt() {  # name, then the setpriv options of the process
      local name=$1 t out
      shift
      t=$(now)
      out=$(timeout 60 setpriv "$@" /usr/bin/linebridge --part dds --channel /run/linebridge/channel.sock \
        --config "$line" --log-level warn 2>&1 | tail -n 1)
      sleep 1
      local refused pid_now
      refused=$(bus_journal_since "$t" | grep -m1 'connection refused' | sed 's/^[0-9.]* [^ ]* //')
      pid_now=$(prop "$dds_unit" MainPID)
      if [ -n "$refused" ] && [ "$pid_now" = "$dds_pid" ] && ! bus_journal_since "$t" | grep -q 'DDS side gone'; then
        pass "channel: $name refused; $dds_unit's main PID $dds_pid unchanged and connected. Bus journal: $refused"
      else
        failed "channel: $name: refused '${refused:-no}', $dds_unit's main PID $dds_pid -> $pid_now; the attempt said: $out"
        bus_journal_since "$t" | tail -n 5
      fi
    }
    attempt "a process of user lbvm-intruder (primary group $(prop "$BUS_UNIT" Group))" \
      --reuid=lbvm-intruder --regid="$(prop "$BUS_UNIT" Group)" --clear-groups
    attempt "a second process of $dds_user while its DDS side is connected" \
      --reuid="$dds_user" --regid="$(prop "$dds_unit" Group)" --groups="$(prop "$BUS_UNIT" Group)"
  fi
fi

# --- 5. a DDS process killed again and again: the unit never gives up, the bus never notices ------
if [ -n "$dds_unit" ] && [ "$SUSTAIN_S" -gt 0 ]; then
  dds_connected 60 >/dev/null || failed "$dds_unit: not connected before the sustained phase"
  bus_pid=$(prop "$BUS_UNIT" MainPID)
  allowed=$((SUSTAIN_GAP_PERIODS * period_ms))
  # The same guest with nothing killed, for comparison: what the emulator alone costs SYNC.
  quiet=$((SUSTAIN_S < 60 ? SUSTAIN_S : 60))
  tq=$(now)
  sleep "$quiet"
  read -r n gap mean span <<<"$(sync_stats "$tq" "$(now)")"
  info "SYNC with nothing killed (the emulator's own jitter), $quiet s: $n frames, mean period $mean ms, largest gap $gap ms, $(gaps_over "$tq" "$(now)" "$allowed") gap(s) over $allowed ms"
  n0=$(prop "$dds_unit" NRestarts)
  say "$dds_unit: killed each time it is active, for $SUSTAIN_S s (NRestarts $n0)"
  # The bus unit's journal as it comes: which DDS process connected, and when. Read from a file
  # (cheap) rather than asking systemd at every turn: under the emulator, a systemctl call every
  # 100 ms costs the guest more than the DDS processes do.
  journalctl -f -n 200 -o short-unix -u "$BUS_UNIT" >/run/lbvm/bus-journal.log 2>&1 &
  jpid=$!
  sleep 1
  t0=$(now)
  t_end=$(awk -v a="$t0" -v d="$SUSTAIN_S" 'BEGIN { printf "%.3f", a + d }')
  kills=0 last=0 gave_up="" turn=0 kill_times=()
  while awk -v n="$(now)" -v e="$t_end" 'BEGIN { exit !(n < e) }'; do
    turn=$((turn + 1))
    if [ $((turn % 10)) = 0 ] && systemctl is-failed --quiet "$dds_unit"; then
      gave_up="$(prop "$dds_unit" ActiveState)/$(prop "$dds_unit" Result)"
      break
    fi
    pid=$(grep -o 'DDS side connected (pid [0-9]*' /run/lbvm/bus-journal.log | tail -n 1 | awk '{ print $NF }')
    if [ -n "$pid" ] && [ "$pid" != "$last" ]; then
      sleep "0.$((RANDOM % 5))"
      if kill -9 "$pid" 2>/dev/null; then
        kills=$((kills + 1))
        kill_times+=("$(now)")
      fi
      last=$pid
    fi
    sleep 0.2
  done
  t1=$(now)
  t_last_kill=${kill_times[-1]:-$t1}
  if [ -n "$gave_up" ]; then
    failed "$dds_unit gave up after $kills kill(s) in $(fmt "$t0" "$t1") s: $gave_up"
    systemctl reset-failed "$dds_unit"; systemctl start "$dds_unit"
  elif [ "$kills" -lt 3 ]; then
    failed "$dds_unit: only $kills kill(s) in $(fmt "$t0" "$t1") s: no DDS process connected to kill"
  else
    pass "$dds_unit: $kills kill(s) of a connected DDS process in $(fmt "$t0" "$t1") s, never failed (no start limit), NRestarts $n0 -> $(prop "$dds_unit" NRestarts)"
  fi
  # After the last kill: back within the longest pause (30 s) and a start.
  limit=$(awk -v m="$MARGIN_S" 'BEGIN { print 30 + m }')
  if back_pid=$(dds_connected "${limit%.*}"); then
    pass "$dds_unit: serving again (main PID $back_pid connected) $(fmt "$t_last_kill" "$(now)") s after the last kill (limit $limit s)"
    sleep 0.5
  else
    failed "$dds_unit: not serving within $limit s of the last kill (state $(prop "$dds_unit" ActiveState)/$(prop "$dds_unit" SubState))"
  fi
  if [ "$(prop "$BUS_UNIT" MainPID)" = "$bus_pid" ]; then
    pass "$BUS_UNIT: main PID $bus_pid unchanged through the sustained kills"
  else
    failed "$BUS_UNIT: main PID $bus_pid -> $(prop "$BUS_UNIT" MainPID) during the sustained kills"
  fi
  read -r n gap mean span <<<"$(sync_stats "$t0" "$(now)")"
  over=$(gaps_over "$t0" "$(now)" "$allowed")
  if awk -v g="$gap" -v a="$allowed" 'BEGIN { exit !(g <= a) }'; then
    pass "SYNC through the sustained kills: $n frames in $span s, mean period $mean ms, largest gap $gap ms <= $SUSTAIN_GAP_PERIODS periods ($allowed ms)"
  else
    failed "SYNC through the sustained kills: largest gap $gap ms > $SUSTAIN_GAP_PERIODS periods ($allowed ms); $over gap(s) over it ($n frames in $span s, mean period $mean ms)"
  fi
  kill "$jpid" 2>/dev/null
  # From each kill to the next DDS process connected (the bus unit's journal).
  back=$(printf '%s\n' "${kill_times[@]}" | awk '
    NR == FNR { k[NR] = $1; nk = NR; next }
    /DDS side connected/ { c[++nc] = $1 + 0 }
    END { j = 1; for (i = 1; i <= nk; i++) { while (j <= nc && c[j] <= k[i]) j++; if (j <= nc) printf "%.1f ", c[j] - k[i] } }' \
    - <(journal_since "$BUS_UNIT" "$t0"))
  info "$dds_unit: from each kill to the next DDS process connected (s): $back"
  # What the journals say of it: the DDS process's back-off, the bus process's alarm.
  dj=$(journal_since "$dds_unit" "$t0")
  bj=$(journal_since "$BUS_UNIT" "$t0")
  waits=$(grep -o 'waits [0-9.]* s before it starts' <<<"$dj" | awk '{ print $2 }' | tr '\n' ' ')
  info "$dds_unit: pauses before starting (back-off, s): ${waits:-none}"
  info "$BUS_UNIT: alarm lines 'no DDS side for': $(grep -c 'no DDS side for' <<<"$bj"); 'a DDS side again': $(grep -c 'a DDS side again' <<<"$bj"); 'DDS side connected': $(grep -c 'DDS side connected' <<<"$bj")"
  # Per 30 s of the phase, as systemd logged them: restarts it scheduled, and times the unit
  # became active (READY=1).
  per30() { awk -v a="$t0" -v p="$1" '$0 ~ p { i = int(($1 - a) / 30); if (i < 0) next; c[i]++; if (i > m) m = i } END { for (i = 0; i <= m; i++) printf "%d ", c[i] }' <<<"$dj"; }
  info "$dds_unit: per 30 s, restarts scheduled: $(per30 'Scheduled restart job'); became active: $(per30 'Started linebridge')"
fi

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
