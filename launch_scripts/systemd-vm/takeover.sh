# shellcheck shell=bash disable=SC2154  # job, failures, MARGIN_S, ALARM_S, SIM: check.sh's
# The hot standby scenario of launch_scripts/systemd-vm.sh --takeover (issue 42, docs/redundancy.md),
# sourced by check.sh in the guest once vcan0 exists, with check.sh's helpers (pass, failed, info,
# prop, span_s, sync_stats, journal_since, finish ...). Never run on the host.
#
# Bridge A runs under the package's units (linebridge-bus.service, linebridge-dds.service) from a
# line file whose bus is `role: standby`, flying master priority 1; bridge B (priority 2, --part
# both, its own line file and state_dir) is a plain process. linebridge-sim plays the devices.
#   1. A starts alone and masters the bus.
#   2. B starts and stands by A.
#   3. A's bus process is frozen (SIGSTOP) until B has taken the bus over, then resumed: A steps
#      back (execv of itself: the same PID) and, under systemd, its unit stays active with the same
#      main PID, no restart, no watchdog kill, READY again; A stands by B. On vcan0 from the resume
#      on: one SYNC producer, no NMT command, no SDO download.
#   4. B is killed (SIGKILL, both its processes): A takes over under systemd, SYNC within
#      takeover_after_ms + a period + TCG_MARGIN_MS, no NMT command, the devices stay operational.
# Parameters (check.conf): HEARTBEAT_MS, TAKEOVER_MS (both bridges' master_heartbeat_ms and
# takeover_after_ms), TCG_MARGIN_MS, STANDBY_HOLD_S (how long A stands by B before B is killed).
HEARTBEAT_MS=${HEARTBEAT_MS:-200}
TAKEOVER_MS=${TAKEOVER_MS:-1000}
TCG_MARGIN_MS=${TCG_MARGIN_MS:-1000}
STANDBY_HOLD_S=${STANDBY_HOLD_S:-0}
bus_unit=linebridge-bus.service
dds_unit=linebridge-dds.service

# --- helpers -------------------------------------------------------------------------------------
later() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a > b) }'; }  # true when $1 > $2 (times, numbers)
deadline_in() { awk -v s="$(now)" -v d="$1" 'BEGIN { printf "%.3f", s + d }'; }
# B's log and A's (through the journal) stamp their lines with the time of day (spdlog, local
# time, the event's own: journald stamps what it reads at once alike): as seconds since the epoch.
midnight=$(date -d 'today 00:00' +%s)
# The time of the first journal line of unit $1 containing $2 and stamped at or after $3 (the
# line's own time when it has one, else the journal's); waits up to $4 s.
wait_journal() {
  local u=$1 text=$2 after=$3 deadline t
  deadline=$(deadline_in "$4")
  while :; do
    t=$(journalctl -u "$u" --since "@${after%.*}" -o short-unix --no-pager 2>/dev/null |
      awk -v a="$after" -v p="$text" -v m="$midnight" '
        $1 + 0 >= a && index($0, p) {
          if ($4 ~ /^[0-9][0-9]:[0-9][0-9]:[0-9][0-9][.][0-9]+$/) { split($4, c, ":"); printf "%.3f\n", m + c[1] * 3600 + c[2] * 60 + c[3] }
          else print $1
          exit }')
    [ -n "$t" ] && { echo "$t"; return 0; }
    later "$(now)" "$deadline" && return 1
    sleep 0.2
  done
}
# The journal line itself (without its stamp and host) of that event.
journal_line() {
  journalctl -u "$1" --since "@${3%.*}" -o short-unix --no-pager 2>/dev/null |
    awk -v a="$3" -v p="$2" '$1 + 0 >= a && index($0, p) { $1 = $2 = ""; sub(/^ +/, ""); print; exit }'
}
b_log=/run/lbvm/bridge-b.log
# The time of the first line of B's log containing $1 stamped after $2; waits up to $3 s.
wait_b_log() {
  local text=$1 after=$2 deadline t
  deadline=$(deadline_in "$3")
  while :; do
    t=$(awk -v m="$midnight" -v a="$after" -v p="$text" '
          index($0, p) { split($1, c, ":"); t = m + c[1] * 3600 + c[2] * 60 + c[3]; if (t > a) { printf "%.3f\n", t; exit } }' "$b_log")
    [ -n "$t" ] && { echo "$t"; return 0; }
    later "$(now)" "$deadline" && return 1
    sleep 0.05
  done
}
# Whether SYNC between two times has one producer: "short unexplained extra". short: gaps under half
# a period; unexplained: those of them that do not end a late run (with the three gaps before it
# they span under 3.5 periods: two producers interleaved make 2); extra: frames beyond one each
# period over the span (the SYNC timer keeps an absolute schedule, so the emulator's jitter moves
# only the ends).
sync_producers() { awk -v a="$1" -v b="$2" -v p="$period_ms" '
  $3 == "080" { t = substr($1, 2, length($1) - 2) + 0
                if (t < a || t > b) next
                if (n) { g = (t - l) * 1000; g3 = g2; g2 = g1; g1 = g0; g0 = g
                         if (g < p / 2) { s++; if (n >= 4 && g0 + g1 + g2 + g3 < 3.5 * p) u++ } }
                else f = t
                l = t; n++ }
  END { printf "%d %d %.1f\n", s, u, (n > 1 ? (n - 1) - (l - f) * 1000 / p : 0) }' /run/lbvm/candump.log; }
# Frames a master must not send to a running line between two times: NMT commands (000h) and SDO
# downloads (a request on 600h + node whose command specifier, the top 3 bits of byte 0, is 0
# (segment) or 1 (initiate)). Prints "nmt sdo_downloads" and lists them in $3.
forbidden_frames() {
  awk -v a="$1" -v b="$2" -v out="$3" '
    { t = substr($1, 2, length($1) - 2) + 0; if (t < a || t > b) next
      if ($3 == "000") { nmt++; print > out }
      else if (length($3) == 3 && $3 >= "601" && $3 <= "67F" && $5 != "") {
        ccs = int((index("0123456789ABCDEF", substr($5, 1, 1)) - 1) / 2)  # the top 3 bits of byte 0
        if (ccs <= 1) { sdo++; print > out } } }
    END { printf "%d %d\n", nmt, sdo }' /run/lbvm/candump.log
}
# Node $1's heartbeats between two times that do not say operational (05): "count first_frame".
not_operational() {
  local id
  id=$(printf '%03X' $((0x700 + $1)))
  awk -v a="$2" -v b="$3" -v id="$id" '
    $3 == id { t = substr($1, 2, length($1) - 2) + 0; if (t < a || t > b) next; n++; if ($5 != "05") { c++; if (!f) f = $0 } }
    END { printf "%d %d %s\n", c, n, f }' /run/lbvm/candump.log
}
# A line of $2 each time unit $1's state, main PID, restarts, watchdog stamp or status change.
watch_unit() {
  local last="" cur
  while :; do
    cur=$(systemctl show -p ActiveState,SubState,MainPID,NRestarts,StatusText "$1" | sort | tr '\n' ' ')
    [ "$cur" != "$last" ] && echo "$(now) $cur" >>"$2"
    last=$cur
    sleep 0.1
  done
}
unit_line() { echo "$(prop "$1" ActiveState)/$(prop "$1" SubState) MainPID $(prop "$1" MainPID) NRestarts $(prop "$1" NRestarts) StatusText '$(prop "$1" StatusText)'"; }

# --- set-up: the two line files, the units' settings, the device ---------------------------------
# The package's example line file on vcan0, its bus a standby: the same for both but for the
# flying master's priority and B's state_dir. Negotiation timings short (the defaults' 1.5 s slot
# per priority would only lengthen the start).
line_for() {  # priority
  sed -e 's#interface: socketcan:can0#interface: socketcan:vcan0#' \
    -e "s#^\\( *\\)role: master.*#\\1role: standby\\n\\1master_heartbeat_ms: $HEARTBEAT_MS\\n\\1takeover_after_ms: $TAKEOVER_MS\\n\\1flying_master: {priority: $1, negotiation_delay_ms: 300, detect_timeout_ms: 200, priority_slot_ms: 300}#" \
    /etc/linebridge/line.yaml
}
line=/etc/linebridge/vm-line.yaml
line_b=/etc/linebridge/vm-line-b.yaml
line_for 1 >"$line"
{ echo "state_dir: /var/lib/lbvm-b"; line_for 2; } >"$line_b"
grep -q 'role: standby' "$line" || { failed "the package's line.yaml has no 'role: master' bus to make a standby"; finish 2; }
use_line "$line"
info "bridge A: the package's units, $line (bus: $(grep -A4 'role: standby' "$line" | sed 's/^ *//' | tr '\n' ' '))"
info "bridge B: --part both, a plain process, $line_b (priority 2, state_dir /var/lib/lbvm-b); SYNC ${period_ms} ms, device node $node"
if out=$(/usr/bin/linebridge --check "$line" --peer "$line_b" 2>&1); then
  pass "linebridge --check A --peer B: the pair is valid"
else
  echo "$out"
  failed "linebridge --check $line --peer $line_b"
  finish 1
fi
stdbuf -oL candump -t a vcan0 >/run/lbvm/candump.log 2>/run/lbvm/candump.err &
# shellcheck disable=SC2034  # check.sh's finish stops it
dump_pid=$!
sleep 0.5
if [ "${SIM:-1}" = 1 ]; then
  systemd-run --quiet --unit=linebridge-vm-sim /usr/bin/linebridge-sim --config "$line" ||
    { failed "cannot start linebridge-sim"; finish 2; }
fi

# --- 1. A under the units, alone: it masters the bus ----------------------------------------------
t0=$(now)
for u in $bus_unit $dds_unit; do
  ts=$(now)
  if ! timeout 120 systemctl start "$u"; then
    systemctl status --no-pager -l "$u"
    failed "$u: systemctl start"
    finish 1
  fi
  info "$u: started (READY=1) after $(fmt "$ts" "$(now)") s: $(unit_line "$u"), WatchdogUSec $(prop "$u" WatchdogUSec)"
done
# (WatchdogUSec reads infinity before the unit has started.)
wd=$(span_s "$bus_unit" WatchdogUSec)
stop_s=$(span_s "$bus_unit" TimeoutStopUSec)
# A freeze of A's bus process must outlast B's takeover_after_ms and end before A's watchdog can
# fire: the process pings every WatchdogSec/2, so a stall shorter than WatchdogSec/2 is always
# survived, one up to WatchdogSec only when the last ping came just before it.
freeze_max=$(awk -v w="$wd" 'BEGIN { printf "%.1f", w / 2 - 0.5 }')
if awk -v t="$TAKEOVER_MS" -v f="$freeze_max" 'BEGIN { exit !(t / 1000 + 1 < f) }'; then
  info "$bus_unit: WatchdogSec ${wd}s, TimeoutStopSec ${stop_s}s: a freeze between takeover_after_ms (${TAKEOVER_MS} ms) and ${freeze_max} s (WatchdogSec/2 less 0.5 s) is possible"
else
  failed "takeover_after_ms ${TAKEOVER_MS} ms + 1 s does not fit under WatchdogSec/2 of $bus_unit (${wd}s): no freeze can outlast the takeover and not the watchdog"
  finish 2
fi

if t=$(wait_journal "$bus_unit" "mastering the bus" "$t0" 30); then
  pass "A masters the bus $(fmt "$t0" "$t") s after its start: $(journal_line "$bus_unit" "mastering the bus" "$t0")"
else
  failed "A: no 'mastering the bus' in its journal within 30 s"
  journal_since "$bus_unit" "$t0" | tail -n 20
  finish 1
fi
if s=$(first_sync_after "$t0" 10) && wait_operational "$node" "$t0" 30; then
  pass "SYNC on vcan0 from A ($(fmt "$t0" "$s") s after its start), device node $node operational"
else
  failed "no SYNC, or device node $node not operational, after A's start"
fi
if wait_journal "$bus_unit" "DDS side connected" "$t0" 60 >/dev/null; then
  pass "$dds_unit: connected to A's bus process ($(journal_line "$bus_unit" "DDS side connected" "$t0"))"
else
  failed "$dds_unit: not connected to A's bus process within 60 s"
fi

# --- 2. B stands by ---------------------------------------------------------------------------------
mkdir -p /var/lib/lbvm-b
tb=$(now)
setsid /usr/bin/linebridge --config "$line_b" --log-level info >"$b_log" 2>&1 </dev/null &
b_pid=$!
if t=$(wait_b_log "standing by the active master" "$tb" 60); then
  pass "B (pid $b_pid, --part both) stands by A $(fmt "$tb" "$t") s after its start: $(grep -m1 'standing by the active master' "$b_log" | cut -d' ' -f4-)"
else
  failed "B: no 'standing by the active master' in its log within 60 s"
  tail -n 20 "$b_log"
  finish 1
fi
b_dds=$(pgrep -P "$b_pid" | head -n 1)
info "B: bus process $b_pid, DDS process ${b_dds:-none}"
# The line with both bridges, nothing frozen: SYNC as the emulator alone makes it (the baseline of
# the short gaps counted below).
tq=$(now)
sleep 5
read -r n gap mean span <<<"$(sync_stats "$tq" "$(now)")"
read -r short unexpl extra <<<"$(sync_producers "$tq" "$(now)")"
info "SYNC with B standing by, 5 s (the emulator's own jitter): $n frames, mean period $mean ms, largest gap $gap ms, $short gap(s) under half a period ($unexpl not ending a late run), $extra frame(s) over one a period"

# --- 3. A frozen past B's takeover, then resumed: it steps back under systemd ---------------------
a_pid=$(prop "$bus_unit" MainPID)
a_n=$(prop "$bus_unit" NRestarts)
d_pid=$(prop "$dds_unit" MainPID)
d_n=$(prop "$dds_unit" NRestarts)
info "before the freeze: $bus_unit $(unit_line "$bus_unit"); $dds_unit $(unit_line "$dds_unit")"
: >/run/lbvm/bus-states.log
: >/run/lbvm/dds-states.log
watch_unit "$bus_unit" /run/lbvm/bus-states.log 2>/dev/null &
w1=$!
watch_unit "$dds_unit" /run/lbvm/dds-states.log 2>/dev/null &
w2=$!
sleep 0.5
t_stop=$(now)
kill -STOP "$a_pid"
took=$(wait_b_log "took the bus over" "$t_stop" "$freeze_max")
took_rc=$?
t_cont=$(now)
kill -CONT "$a_pid"
frozen=$(fmt "$t_stop" "$t_cont")
if [ "$took_rc" = 0 ]; then
  pass "A's bus process ($a_pid) frozen $frozen s (kill -STOP .. kill -CONT): B took the bus over $(fmt "$t_stop" "$took") s after the freeze: $(grep -m1 'took the bus over' "$b_log" | cut -d' ' -f4-)"
else
  failed "B did not take the bus over within $frozen s of A's freeze (limit ${freeze_max} s): A resumed"
  tail -n 20 "$b_log"
fi
read -r n gap1 mean span <<<"$(sync_stats "$(awk -v t="$t_stop" 'BEGIN { printf "%.6f", t - 1 }')" "$t_cont")"
info "SYNC gap at B's takeover (largest gap from 1 s before the freeze to SIGCONT: A's last SYNC to B's first): $gap1 ms (takeover_after_ms $TAKEOVER_MS)"
if t_sb=$(wait_journal "$bus_unit" "stepping back to standby" "$t_cont" 30); then
  pass "A steps back $(fmt "$t_cont" "$t_sb") s after SIGCONT: $(journal_line "$bus_unit" "stepping back to standby" "$t_cont")"
else
  failed "A: no 'stepping back to standby' in its journal within 30 s of SIGCONT"
  t_sb=$t_cont
fi
if t_st=$(wait_journal "$bus_unit" "standing by the active master" "$t_sb" 60); then
  pass "A stands by B $(fmt "$t_sb" "$t_st") s after stepping back: $(journal_line "$bus_unit" "standing by the active master" "$t_sb")"
else
  failed "A: no 'standing by the active master' in its journal within 60 s of stepping back"
  t_st=$(now)
fi
# systemd's timers that a step back could run into: the stop timeout (STOPPING=1) and the watchdog.
settle=$(awk -v w="$wd" -v s="$stop_s" 'BEGIN { printf "%d", (w > s ? w : s) + 5 }')
say "watching $bus_unit for $settle s (WatchdogSec ${wd}s, TimeoutStopSec ${stop_s}s)"
sleep "$settle"
kill "$w1" "$w2" 2>/dev/null
wait "$w1" "$w2" 2>/dev/null
t_settled=$(now)
j=$(journal_since "$bus_unit" "$t_stop")
echo "--- $bus_unit: journal from the freeze on (systemd's own lines and A's warnings) ---"
grep -E 'systemd\[1\]|warn|error|critical|flying master|serving|systemd watchdog' <<<"$j" | sed 's/^[0-9.]* [^ ]* //' | head -n 60
echo "--- $bus_unit: state changes (systemctl show, every 0.1 s) ---"
cat /run/lbvm/bus-states.log
echo "--- $dds_unit: state changes ---"
cat /run/lbvm/dds-states.log
a_pid1=$(prop "$bus_unit" MainPID)
a_n1=$(prop "$bus_unit" NRestarts)
st="$(prop "$bus_unit" ActiveState)/$(prop "$bus_unit" SubState)"
ok=1
[ "$a_pid1" = "$a_pid" ] || { ok=0; failed "$bus_unit: MainPID $a_pid -> $a_pid1 across the step back (want the same: execv)"; }
[ "$a_n1" = "$a_n" ] || { ok=0; failed "$bus_unit: NRestarts $a_n -> $a_n1 across the step back (want unchanged)"; }
[ "$st" = active/running ] || { ok=0; failed "$bus_unit: $st $settle s after the step back (want active/running)"; }
# systemd's own lines on the unit: what it did about the step back (nothing that stops or kills).
sysj=$(grep 'systemd\[1\]' <<<"$j" | sed 's/^[0-9.]* [^ ]* //')
info "$bus_unit: systemd's journal lines from the freeze on: $([ -n "$sysj" ] && tr '\n' ';' <<<"$sysj" || echo none)"
bad_sys=$(grep -E 'Watchdog timeout|timed out|Killing|Main process exited|Failed|Scheduled restart|Stopping|Stopped|Deactivated' <<<"$sysj")
if [ -n "$bad_sys" ]; then
  ok=0
  failed "$bus_unit: systemd acted on the step back: $(head -n 6 <<<"$bad_sys" | tr '\n' ';')"
fi
# The states systemd showed from the resume on, and whether the new image said READY=1: its status
# text is the one READY=1 carries ("N bus loop(s) running") after the step back's.
seen=$(awk -v a="$t_cont" '$1 + 0 >= a { for (i = 2; i <= NF; i++) if ($i ~ /^ActiveState=/) { s = substr($i, 13); if (!(s in k)) { k[s] = 1; o = o (o ? "," : "") s } } } END { print o }' /run/lbvm/bus-states.log)
status_after=$(prop "$bus_unit" StatusText)
statuses=$(awk -v a="$t_cont" '$1 + 0 >= a { sub(/.*StatusText=/, ""); print }' /run/lbvm/bus-states.log | uniq | tr '\n' '|')
info "$bus_unit from SIGCONT on: ActiveState seen $seen; StatusText $statuses"
# How long systemd showed it reloading: from RELOADING=1 to the new image's READY=1 (as polled:
# each systemctl call takes its time under the emulator).
reload_s=$(awk '/ActiveState=reloading/ && !r { r = $1 } r && /ActiveState=active/ { printf "%.2f", $1 - r; exit }' /run/lbvm/bus-states.log)
if grep -q 'another master won the bus' <<<"$statuses" && grep -q 'bus loop(s) running' <<<"$status_after"; then
  pass "$bus_unit: READY=1 again from the new image: StatusText went '$(tr '|' '\n' <<<"$statuses" | grep -m1 'another master won the bus' | sed 's/ SubState=.*//')' -> '$status_after' (ActiveState seen: $seen)"
else
  ok=0
  failed "$bus_unit: no READY=1 of the new image seen: StatusText now '$status_after', from SIGCONT on: $statuses (ActiveState seen: $seen)"
fi
wts=$(prop "$bus_unit" WatchdogTimestampMonotonic)
mono_st=$(awk -v n="$(now)" -v s="$t_st" -v u="$(awk '{ print $1 }' /proc/uptime)" 'BEGIN { printf "%d", (u - (n - s)) * 1e6 }')
if [ "${wts:-0}" -gt "$mono_st" ]; then
  pass "$bus_unit: fed by the new image: WatchdogTimestamp $(prop "$bus_unit" WatchdogTimestamp), after A stood by again"
else
  ok=0
  failed "$bus_unit: WatchdogTimestamp $(prop "$bus_unit" WatchdogTimestamp) not after A stood by again"
fi
[ "$ok" = 1 ] && pass "$bus_unit under systemd across the step back: $st, MainPID $a_pid unchanged (execv), NRestarts $a_n unchanged, no watchdog or stop timeout, $settle s watched"
info "$bus_unit: $(systemctl show -p StatusText,ActiveState,SubState,MainPID,NRestarts,WatchdogTimestamp "$bus_unit" | tr '\n' ' ')"
# The DDS side: its channel ended with the old image, so its process ends and systemd starts
# another (Restart=always), which waits in the new channel's backlog while A stands by.
d_pid1=$(prop "$dds_unit" MainPID)
d_n1=$(prop "$dds_unit" NRestarts)
dj=$(journal_since "$dds_unit" "$t_stop")
info "$dds_unit after the step back: $(unit_line "$dds_unit") (before: MainPID $d_pid NRestarts $d_n)"
info "$dds_unit journal: $(grep -E 'this DDS side ends|Main process exited|Scheduled restart|Started|Starting|bus process pid|timed out|Failed' <<<"$dj" | sed 's/^[0-9.]* [^ ]* //' | head -n 8 | tr '\n' ';')"
d_state=$(prop "$dds_unit" ActiveState)
if [ "$d_pid1" != "$d_pid" ] && [ "$d_n1" -gt "$d_n" ] && grep -q 'this DDS side ends' <<<"$dj" &&
    { [ "$d_state" = activating ] || [ "$d_state" = active ]; }; then
  pass "$dds_unit: its process ended with the old image's channel and systemd started another (MainPID $d_pid -> $d_pid1, NRestarts $d_n -> $d_n1), $d_state: it waits in the backlog of A's channel while A stands by"
else
  failed "$dds_unit after the step back: $(unit_line "$dds_unit") (before MainPID $d_pid NRestarts $d_n); want a new process, activating or active"
fi
read -r nmt sdo <<<"$(forbidden_frames "$t_cont" "$t_settled" /run/lbvm/forbidden-3.log)"
if [ "$nmt" = 0 ] && [ "$sdo" = 0 ]; then
  pass "vcan0 from SIGCONT to $(fmt "$t_cont" "$t_settled") s after: no NMT command (000h), no SDO download (600h + node)"
else
  failed "vcan0 from SIGCONT on: $nmt NMT command(s), $sdo SDO download(s): $(head -n 3 /run/lbvm/forbidden-3.log | tr '\n' ';')"
fi
read -r n gap mean span <<<"$(sync_stats "$t_cont" "$t_settled")"
read -r short unexpl extra <<<"$(sync_producers "$t_cont" "$t_settled")"
if [ "$unexpl" -le 2 ] && awk -v e="$extra" 'BEGIN { exit !(e < 2) }'; then
  pass "one SYNC producer from SIGCONT on: $n frames in $span s, mean period $mean ms (configured $period_ms), $extra frame(s) over one a period; $short gap(s) under half a period, $unexpl of them not ending a late run (allowed 2); largest gap $gap ms"
else
  failed "two SYNC producers from SIGCONT on? $n frames in $span s, mean period $mean ms (configured $period_ms), $extra frame(s) over one a period; $short gap(s) under half a period, $unexpl of them not ending a late run (allowed 2)"
fi
read -r bad nhb first_bad <<<"$(not_operational "$node" "$t_stop" "$t_settled")"
if [ "$bad" = 0 ] && [ "$nhb" -gt 0 ]; then
  pass "device node $node operational throughout (all $nhb heartbeats 05 from the freeze on)"
else
  failed "device node $node: $bad of $nhb heartbeats not operational from the freeze on (first: $first_bad)"
fi

# --- A stands by for STANDBY_HOLD_S: what systemd does with its DDS unit meanwhile -----------------
if [ "$STANDBY_HOLD_S" -gt 0 ]; then
  say "A stands by for $STANDBY_HOLD_S s ($dds_unit: TimeoutStartSec $(prop "$dds_unit" TimeoutStartUSec))"
  th=$(now)
  sleep "$STANDBY_HOLD_S"
  dj=$(journal_since "$dds_unit" "$th")
  info "$dds_unit while A stood by $STANDBY_HOLD_S s: $(unit_line "$dds_unit"); start timeouts: $(grep -c 'Start operation timed out\|start operation timed out' <<<"$dj"), 'Failed with result' $(grep -c 'Failed with result' <<<"$dj"), restarts scheduled $(grep -c 'Scheduled restart' <<<"$dj")"
  grep -E 'systemd\[1\]' <<<"$dj" | sed 's/^[0-9.]* [^ ]* //' | head -n 8
  # Waiting in the backlog is a standby DDS side's normal state: READY=1 with that status and its
  # watchdog fed, so systemd neither times its start out nor restarts it.
  if [ "$(prop "$dds_unit" ActiveState)" = active ] && prop "$dds_unit" StatusText | grep -q 'waiting to be let in' &&
      ! grep -qi 'start operation timed out\|Failed with result\|Scheduled restart\|Watchdog timeout' <<<"$dj"; then
    pass "$dds_unit while A stood by $STANDBY_HOLD_S s: active, StatusText '$(prop "$dds_unit" StatusText)', no start timeout, no restart"
  else
    failed "$dds_unit while A stood by $STANDBY_HOLD_S s: $(unit_line "$dds_unit"); want active, waiting to be let in, no timeout or restart"
  fi
  if [ "$(prop "$bus_unit" MainPID)" = "$a_pid" ] && [ "$(prop "$bus_unit" NRestarts)" = "$a_n" ]; then
    pass "$bus_unit: MainPID $a_pid, NRestarts $a_n while A stood by"
  else
    failed "$bus_unit while A stood by: $(unit_line "$bus_unit")"
  fi
fi

# --- 4. B killed: A takes over under systemd --------------------------------------------------------
d_pid2=$(prop "$dds_unit" MainPID)
b_dds=$(pgrep -P "$b_pid" | head -n 1)
t_kill=$(now)
kill -9 "$b_pid" ${b_dds:+"$b_dds"}
if t_took=$(wait_journal "$bus_unit" "took the bus over" "$t_kill" 30); then
  pass "A takes the bus over under systemd $(fmt "$t_kill" "$t_took") s after B's SIGKILL: $(journal_line "$bus_unit" "took the bus over" "$t_kill")"
else
  failed "A: no 'took the bus over' in its journal within 30 s of B's SIGKILL"
  t_took=$(now)
fi
sleep 3
read -r n gap2 mean span <<<"$(sync_stats "$(awk -v t="$t_kill" 'BEGIN { printf "%.6f", t - 1 }')" "$(now)")"
limit2=$((TAKEOVER_MS + period_ms + TCG_MARGIN_MS))
if awk -v g="$gap2" -v l="$limit2" 'BEGIN { exit !(g <= l) }'; then
  pass "SYNC gap at A's takeover (largest from 1 s before B's kill to 3 s after A's takeover: B's last SYNC to A's first): $gap2 ms <= takeover_after_ms + a period + TCG margin ($limit2 ms)"
else
  failed "SYNC gap at A's takeover: $gap2 ms > $limit2 ms (takeover_after_ms $TAKEOVER_MS + $period_ms + $TCG_MARGIN_MS)"
fi
if wait_operational "$node" "$t_took" 10; then :; fi
t_end4=$(now)
read -r nmt sdo <<<"$(forbidden_frames "$t_kill" "$t_end4" /run/lbvm/forbidden-4.log)"
if [ "$nmt" = 0 ] && [ "$sdo" = 0 ]; then
  pass "vcan0 from B's kill to $(fmt "$t_kill" "$t_end4") s after: no NMT command (000h), no SDO download"
else
  failed "vcan0 from B's kill on: $nmt NMT command(s), $sdo SDO download(s): $(head -n 3 /run/lbvm/forbidden-4.log | tr '\n' ';')"
fi
read -r bad nhb first_bad <<<"$(not_operational "$node" "$t_kill" "$t_end4")"
if [ "$bad" = 0 ] && operational_after "$node" "$t_took"; then
  pass "device node $node operational through A's takeover ($nhb heartbeats 05 from the kill on, one after the takeover)"
else
  failed "device node $node after A's takeover: $bad of $nhb heartbeats not operational (first: $first_bad)"
fi
read -r n gap mean span <<<"$(sync_stats "$t_took" "$t_end4")"
read -r short unexpl extra <<<"$(sync_producers "$t_took" "$t_end4")"
info "SYNC after A's takeover: $n frames in $span s, mean period $mean ms, largest gap $gap ms, $short gap(s) under half a period ($unexpl not ending a late run), $extra frame(s) over one a period"
if [ "$(prop "$bus_unit" MainPID)" = "$a_pid" ] && [ "$(prop "$bus_unit" NRestarts)" = "$a_n" ] &&
    [ "$(prop "$bus_unit" ActiveState)" = active ]; then
  pass "$bus_unit after A's takeover: $(unit_line "$bus_unit")"
else
  failed "$bus_unit after A's takeover: $(unit_line "$bus_unit") (want active, MainPID $a_pid, NRestarts $a_n)"
fi
# Its DDS side is served from the takeover on: the process waiting in the backlog is let in and
# says READY=1 (the bus process's journal and the DDS unit's, against A's takeover).
dlimit=$((30 + MARGIN_S))
if t_conn=$(wait_journal "$bus_unit" "DDS side connected" "$t_took" "$dlimit") &&
    t_ready=$(wait_journal "$dds_unit" "ready:" "$t_took" "$dlimit"); then
  sleep 0.5
  p=$(prop "$dds_unit" MainPID)
  if [ "$(prop "$dds_unit" ActiveState)" = active ] && journal_line "$bus_unit" "DDS side connected" "$t_took" | grep -q "(pid ${p}[,)]"; then
    pass "$dds_unit: its process let in $(fmt "$t_took" "$t_conn") s and READY=1 $(fmt "$t_took" "$t_ready") s after A's takeover (journal), active, MainPID $d_pid2 -> $p ($([ "$p" = "$d_pid2" ] && echo 'the process that waited in the backlog' || echo 'another process'))"
  else
    failed "$dds_unit after A's takeover: $(unit_line "$dds_unit"); bus journal: $(journal_line "$bus_unit" "DDS side connected" "$t_took")"
  fi
  info "$bus_unit's channel at A's takeover: $(journal_since "$bus_unit" "$t_took" | awk -v a="$t_took" '$1 + 0 >= a && /channel/ { $1 = $2 = ""; sub(/^ +/, ""); print }' | head -n 3 | tr '\n' ';')"
else
  failed "$dds_unit: not let in and READY=1 within $dlimit s of A's takeover: $(unit_line "$dds_unit")"
fi

# --- the figures ----------------------------------------------------------------------------------
info "figures: freeze $frozen s; B's takeover $(fmt "$t_stop" "${took:-$t_cont}") s after the freeze, SYNC gap $gap1 ms; SIGCONT to 'stepping back' $(fmt "$t_cont" "$t_sb") s; 'stepping back' to 'standing by' $(fmt "$t_sb" "$t_st") s; $bus_unit reloading (RELOADING=1 to the new image's READY=1, polled) ${reload_s:-?} s; A's takeover $(fmt "$t_kill" "$t_took") s after B's SIGKILL, SYNC gap $gap2 ms"
for u in $bus_unit $dds_unit; do info "$u at the end: $(unit_line "$u")"; done
info "candump: $(grep -c ' 080 ' /run/lbvm/candump.log) SYNC frames, $(wc -l </run/lbvm/candump.log) frames in all"
cp "$b_log" "$job/bridge-b.log" 2>/dev/null
cp /run/lbvm/bus-states.log /run/lbvm/dds-states.log "$job/" 2>/dev/null
say "done: $failures check(s) failed"
[ "$failures" = 0 ] && finish 0
finish 1
