#!/usr/bin/env bash
# The package's systemd units under a real systemd (PID 1): builds a Debian 12 root with
# mmdebstrap (systemd as init, the linebridge .deb of launch_scripts/package.sh with its
# dependencies, can-utils, iproute2), boots it in qemu with Debian's kernel (as vcan-run.sh does:
# software emulation, no network interface at all) and runs launch_scripts/systemd-vm/check.sh in
# the guest as a oneshot unit. The check, on vcan0 with the package's own line file and units:
# the service starts (Type=notify, READY=1) and SYNC runs on vcan0 (candump -t a); kill -9 of each
# unit's main process: systemd restarts it (Restart=on-failure), the other units' main PIDs and,
# when the bus unit is not the one killed, its SYNC (no gap > 3 periods) untouched; kill -STOP of
# each: the watchdog fires within WatchdogSec, systemd kills and restarts it (journal, NRestarts,
# MainPID); the units' users differ and the DDS unit's cannot signal the bus process, another user
# of the bus unit's group and a second process of the DDS unit's user are refused on the channel;
# the DDS unit's main process killed each time it is active for --sustain seconds: the unit never
# gives up, the bus unit's main PID never changes, SYNC never gaps over --sustain-gap-periods.
# Prints the guest's log and a summary with the measured times. Slow (minutes): not in CI.
# --takeover runs instead the hot standby scenario of issue 42 (systemd-vm/takeover.sh,
# docs/redundancy.md): bridge A under the package's units, its bus `role: standby` (flying master
# priority 1), bridge B (priority 2, --part both) a plain process, linebridge-sim the device. A
# masters, B stands by; A's bus process is frozen (kill -STOP) until B has taken the bus over, then
# resumed: A steps back (execv, the same PID), and its unit must stay active (reloading until the
# new image's READY=1) with its MainPID and NRestarts, no watchdog or stop timeout, A standing by
# B, its DDS unit's process replaced and waiting; on vcan0 from the resume one SYNC producer, no NMT
# command, no SDO download. Then B is killed (SIGKILL): A takes over under systemd (SYNC gap within
# takeover_after_ms + a period + --tcg-margin-ms, no NMT, the device operational) and its DDS unit
# serves again. 3 to 4 minutes.
#   launch_scripts/systemd-vm.sh --sustain 180     # the 3-minute run of issue 41
#   launch_scripts/systemd-vm.sh --takeover        # a step back and two takeovers under systemd (issue 42)
#   launch_scripts/systemd-vm.sh [OPTIONS]
# Options:
#   --units "A.service B.service"  the units under test, in start order (default linebridge-bus.service linebridge-dds.service;
#   --bus-unit UNIT    the unit that sends SYNC (default: the first of --units)
#   --margin S         slack over WatchdogSec + RestartSec for a restart under TCG (default 20)
#   --gap-periods N    largest SYNC gap while a non-bus unit is killed, in periods (default 3)
#   --no-sim           no linebridge-sim for the line's device (the bus then has only SYNC and NMT)
#   --sustain S        seconds of the DDS unit's main process killed each time it is active (default 40; 0: none)
#   --sustain-gap-periods N  largest SYNC gap allowed meanwhile, in periods (default 2)
#   --alarm S          the bus unit's alarm without a DDS side (LINEBRIDGE_DDS_ABSENT_ALARM_S, default 5)
#   --build DIR        build directory for package.sh (default build)
#   --deb FILE         use this .deb instead of running package.sh
#   --timeout S        stop the VM after S seconds (default 900)
#   --image-only       build (or find in the cache) the root image and exit
#   --takeover         the hot standby scenario (launch_scripts/systemd-vm/takeover.sh) instead of the checks above
#   --master-heartbeat-ms MS  --takeover: both bridges' master_heartbeat_ms (default 200)
#   --takeover-after-ms MS    --takeover: both bridges' takeover_after_ms (default 1000; under WatchdogSec/2 - 1.5 s)
#   --tcg-margin-ms MS        --takeover: slack on takeover_after_ms + a period for a takeover's SYNC gap (default 1000)
#   --standby-hold S   --takeover: how long A stands by B after its step back, before B is killed (default 100:
#                      past the DDS unit's TimeoutStartSec, which a standby's DDS unit runs into; 0: at once)
# Cache: ${LINEBRIDGE_VM_CACHE:-~/.cache/linebridge-vm} (the kernel, shared with vcan-run.sh) and
# its systemd-root/ (the mmdebstrap base as a tarball, the root image per .deb). Results of the last
# run: BUILD_DIR/systemd-vm/ (check.log, summary.txt, journal.txt, candump.log, console.log; with
# --takeover also bridge-b.log and the units' states across the step back, bus-states.log, dds-states.log).
# Exit status: 0 every check passed, 1 a check failed, 2 the check could not run, 124 timeout,
# 125 this script failed. Needs root (mmdebstrap, chroot, mke2fs -d of a root-owned tree).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
units="linebridge-bus.service linebridge-dds.service"
bus_unit=""
margin=20
gap_periods=3
sim=1
build=${LINEBRIDGE_BUILD_DIR:-build}
deb=""
timeout_s=900
image_only=0
sustain=40
sustain_gap=2
alarm=5
takeover=0
heartbeat_ms=200
takeover_ms=1000
tcg_margin_ms=1000
standby_hold=100

die() { echo "systemd-vm: $*" >&2; exit 125; }
say() { echo "systemd-vm: $*" >&2; }
usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --units) units=${2:?}; shift 2 ;;
    --bus-unit) bus_unit=${2:?}; shift 2 ;;
    --margin) margin=${2:?}; shift 2 ;;
    --gap-periods) gap_periods=${2:?}; shift 2 ;;
    --no-sim) sim=0; shift ;;
    --sustain) sustain=${2:?}; shift 2 ;;
    --sustain-gap-periods) sustain_gap=${2:?}; shift 2 ;;
    --alarm) alarm=${2:?}; shift 2 ;;
    --build) build=${2:?}; shift 2 ;;
    --deb) deb=${2:?}; shift 2 ;;
    --timeout) timeout_s=${2:?}; shift 2 ;;
    --image-only) image_only=1; shift ;;
    --takeover) takeover=1; shift ;;
    --master-heartbeat-ms) heartbeat_ms=${2:?}; shift 2 ;;
    --takeover-after-ms) takeover_ms=${2:?}; shift 2 ;;
    --tcg-margin-ms) tcg_margin_ms=${2:?}; shift 2 ;;
    --standby-hold) standby_hold=${2:?}; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) die "unknown argument $1 (see --help)" ;;
  esac
done
[ -n "$bus_unit" ] || bus_unit=${units%% *}
[ "$(id -u)" -eq 0 ] || die "needs root (mmdebstrap, chroot, mke2fs of a root-owned tree)"
cd "$root"
t_start=$(date +%s)

# --- host packages, kernel -------------------------------------------------------------------------
missing=()
for p in mmdebstrap qemu-system-x86 busybox-static e2fsprogs xz-utils; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if ((${#missing[@]})); then
  say "installing ${missing[*]}"
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}" >&2 ||
    die "apt-get could not install ${missing[*]}"
fi
# The kernel (Debian's, unpacked into the cache, uncompressed vmlinux) as vcan-run.sh prepares it.
"$here/vcan-run.sh" --vm --setup >&2 || die "vcan-run.sh --vm --setup failed"
cache=${LINEBRIDGE_VM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/linebridge-vm}
kver=${LINEBRIDGE_VM_KERNEL:-$(cat "$cache/kernel")}
kver=${kver#linux-image-}
kdir="$cache/$kver"
[ -s "$kdir/vmlinux" ] || die "no kernel in $kdir"
rdir="$cache/systemd-root"
mkdir -p "$rdir"
exec 9>"$rdir/lock"
flock 9

# --- the package ----------------------------------------------------------------------------------
if [ -z "$deb" ]; then
  say "building the package (launch_scripts/package.sh $build)"
  "$here/package.sh" "$build" >"$rdir/package.log" 2>&1 || { tail -n 30 "$rdir/package.log" >&2; die "package.sh failed"; }
  deb=$(tail -n 1 "$rdir/package.log")
fi
[ -f "$deb" ] || die "no package at '$deb'"
deb=$(cd "$(dirname "$deb")" && pwd)/$(basename "$deb")

# --- the Debian base (mmdebstrap), cached by its package list -------------------------------------
# The package's own dependencies (names, without versions) go into the base so that installing a
# new build of the .deb needs no network: dpkg -i in a chroot.
deps=$(dpkg-deb -f "$deb" Depends | tr ',' '\n' | sed 's/(.*)//; s/|.*//; s/ //g' | grep -v '^$' | sort -u | tr '\n' ',')
pkgs="systemd-sysv,kmod,procps,iproute2,can-utils,${deps%,}"
mirrors=("deb http://deb.debian.org/debian bookworm main"
  "deb http://deb.debian.org/debian bookworm-updates main"
  "deb http://deb.debian.org/debian-security bookworm-security main")
base_key=$(printf '%s\n' "$pkgs" "${mirrors[@]}" minbase | md5sum | cut -c1-12)
base="$rdir/base-$base_key.tar"
if [ ! -s "$base" ]; then
  say "building the Debian 12 base with mmdebstrap (packages: $pkgs): a few minutes, once"
  t0=$(date +%s)
  mmdebstrap --quiet --variant=minbase --include="$pkgs" bookworm "$base.tmp.tar" "${mirrors[@]}" >&2 ||
    { rm -f "$base.tmp.tar"; die "mmdebstrap failed"; }
  mv "$base.tmp.tar" "$base"
  find "$rdir" -maxdepth 1 -name 'base-*.tar' ! -name "base-$base_key.tar" -delete
  say "base built in $(($(date +%s) - t0)) s: $(du -h "$base" | cut -f1)"
fi

# --- the root image: base + the .deb + the check, cached by their contents -------------------------
img_key=$(cat "$base" "$deb" "$here"/systemd-vm/* | md5sum | cut -c1-12)
img_key=$(printf '%s %s %s' "$img_key" "$kver" "$(md5sum <"$here/systemd-vm/initramfs-init.sh")" | md5sum | cut -c1-12)
image="$rdir/root-$img_key.img"
initramfs="$rdir/initramfs-$img_key.cpio"
# Modules the guest loads before its root exists (the rest of the kernel's modules are not needed).
want=" virtio_mmio virtio_blk crc32c_generic ext4 9p 9pnet_virtio virtio_console can can_raw can_dev vcan "
mods=$(awk -F: -v want="$want" '
  { n = $1; sub(/.*\//, "", n); sub(/\.ko$/, "", n); gsub(/-/, "_", n) }
  index(want, " " n " ") { print $1; print $2 }' "$kdir/root/lib/modules/$kver/modules.dep" | tr ' ' '\n' | sort -u)
copy_modules() {  # into tree $1
  local m
  for m in $mods; do
    mkdir -p "$1/lib/modules/$kver/$(dirname "$m")"
    cp "$kdir/root/lib/modules/$kver/$m" "$1/lib/modules/$kver/$m"
  done
  /bin/busybox depmod -b "$1" "$kver"
}
if [ ! -s "$image" ] || [ ! -s "$initramfs" ]; then
  say "building the root image ($(basename "$deb"))"
  t0=$(date +%s)
  tree=$(mktemp -d "${TMPDIR:-/tmp}/systemd-vm-root.XXXXXX")
  trap 'rm -rf "$tree"' EXIT
  tar -C "$tree" --numeric-owner -xpf "$base"
  [ -c "$tree/dev/null" ] || mknod -m 666 "$tree/dev/null" c 1 3
  cp "$deb" "$tree/tmp/linebridge.deb"
  chroot "$tree" dpkg -i /tmp/linebridge.deb >"$rdir/dpkg.log" 2>&1 || { cat "$rdir/dpkg.log" >&2; die "dpkg -i of the package in the root failed"; }
  rm "$tree/tmp/linebridge.deb"
  install -D -m 755 "$here/systemd-vm/check.sh" "$tree/usr/local/lib/linebridge-vm/check.sh"
  install -D -m 644 "$here/systemd-vm/takeover.sh" "$tree/usr/local/lib/linebridge-vm/takeover.sh"
  install -D -m 644 "$here/systemd-vm/linebridge-vm-check.service" "$tree/etc/systemd/system/linebridge-vm-check.service"
  mkdir -p "$tree/etc/systemd/system/multi-user.target.wants" "$tree/lbjob"
  ln -sf ../linebridge-vm-check.service "$tree/etc/systemd/system/multi-user.target.wants/"
  cat >"$tree/etc/fstab" <<'FSTAB'
/dev/vda  /       ext4  rw,noatime  0 0
lbjob     /lbjob  9p    trans=virtio,version=9p2000.L,cache=none,msize=262144  0 0
FSTAB
  echo linebridge-vm >"$tree/etc/hostname"
  # A machine id: no first-boot set-up. Nothing that would wait for a network or a terminal.
  tr -d - </proc/sys/kernel/random/uuid >"$tree/etc/machine-id"
  for u in apt-daily.timer apt-daily-upgrade.timer e2scrub_all.timer e2scrub_reap.service fstrim.timer \
      getty@tty1.service serial-getty@ttyS0.service systemd-networkd-wait-online.service; do
    ln -sf /dev/null "$tree/etc/systemd/system/$u"
  done
  copy_modules "$tree"
  size=$(( $(du -sm "$tree" | cut -f1) + 384 ))
  rm -f "$image.tmp"
  mke2fs -q -t ext4 -L lbroot -d "$tree" "$image.tmp" "${size}M" >/dev/null || die "mke2fs -d failed"
  # The initramfs: busybox, its /init, the modules above.
  ird=$(mktemp -d "${TMPDIR:-/tmp}/systemd-vm-initrd.XXXXXX")
  mkdir -p "$ird/bin"
  cp /bin/busybox "$ird/bin/busybox"
  install -m 755 "$here/systemd-vm/initramfs-init.sh" "$ird/init"
  copy_modules "$ird"
  (cd "$ird" && find . | /bin/busybox cpio -o -H newc >"$initramfs.tmp" 2>/dev/null) || die "cannot build the initramfs"
  rm -rf "$ird" "$tree"
  trap - EXIT
  find "$rdir" -maxdepth 1 \( -name 'root-*.img' -o -name 'initramfs-*.cpio' \) -delete
  mv "$image.tmp" "$image"
  mv "$initramfs.tmp" "$initramfs"
  say "root image built in $(($(date +%s) - t0)) s: ${size} MiB ext4"
fi
flock -u 9
[ "$image_only" = 1 ] && { echo "$image"; exit 0; }

# --- the run --------------------------------------------------------------------------------------
job=$(mktemp -d "${TMPDIR:-/tmp}/systemd-vm.XXXXXX")
trap 'rm -rf "$job"' EXIT
printf 'UNITS=%q\nBUS_UNIT=%q\nMARGIN_S=%q\nGAP_PERIODS=%q\nSIM=%q\nSUSTAIN_S=%q\nSUSTAIN_GAP_PERIODS=%q\nALARM_S=%q\n' \
  "$units" "$bus_unit" "$margin" "$gap_periods" "$sim" "$sustain" "$sustain_gap" "$alarm" >"$job/check.conf"
printf 'TAKEOVER=%q\nHEARTBEAT_MS=%q\nTAKEOVER_MS=%q\nTCG_MARGIN_MS=%q\nSTANDBY_HOLD_S=%q\n' \
  "$takeover" "$heartbeat_ms" "$takeover_ms" "$tcg_margin_ms" "$standby_hold" >>"$job/check.conf"
khz=$(awk -F: '/^cpu MHz/ { printf "%d", $2 * 1000; exit }' /proc/cpuinfo)
[ -n "$khz" ] || khz=2000000
# shellcheck disable=SC2054  # qemu's options are comma-separated by design
q=(qemu-system-x86_64
  -M microvm,x-option-roms=off,rtc=on,pit=on,pic=off,isa-serial=on,acpi=on
  -accel tcg,thread=multi -cpu max -m 1024 -smp 2
  -nodefaults -no-user-config -display none -nic none -no-reboot
  -kernel "$kdir/vmlinux" -initrd "$initramfs"
  -append "console=ttyS0 quiet cryptomgr.notests tsc_early_khz=$khz panic=-1 systemd.show_status=auto"
  -serial "file:$job/console.log"
  -drive "file=$image,format=raw,if=none,id=root,snapshot=on"
  -device virtio-blk-device,drive=root
  -fsdev "local,id=lbjob,path=$job,security_model=none"
  -device virtio-9p-device,fsdev=lbjob,mount_tag=lbjob)
say "booting the guest (systemd as PID 1; units: $units; bus unit: $bus_unit)"
t_boot=$(date +%s.%N)
qrc=0
timeout -k 10 "$timeout_s" "${q[@]}" </dev/null >"$job/qemu.log" 2>&1 || qrc=$?
t_end=$(date +%s.%N)
out="$build/systemd-vm"
rm -rf "$out"
mkdir -p "$out"
cp "$job"/*.log "$job"/*.txt "$out"/ 2>/dev/null || true
if [ ! -s "$job/rc" ]; then
  {
    echo "systemd-vm: the guest stopped without a result (qemu exit $qrc$([ "$qrc" = 124 ] && echo ", timeout ${timeout_s}s"))"
    echo "--- qemu ---"; tail -n 20 "$job/qemu.log"
    echo "--- console ---"; tail -n 60 "$job/console.log"
    [ -s "$job/check.log" ] && { echo "--- check.log ---"; cat "$job/check.log"; }
  } >&2
  [ "$qrc" = 124 ] && exit 124
  exit 125
fi
rc=$(cat "$job/rc")
cat "$job/check.log"
echo
cat "$job/summary.txt"
boot_s=$(awk '/Reached target.*[Mm]ulti-[Uu]ser/ { print $1; exit }' "$job/journal.txt")
first=$(awk 'NR == 1 { print $1 }' "$job/journal.txt")
echo "== times: VM run $(awk -v a="$t_boot" -v b="$t_end" 'BEGIN { printf "%.1f", b - a }') s (qemu start to power-off)$([ -n "$boot_s" ] && [ -n "$first" ] && awk -v a="$first" -v b="$boot_s" 'BEGIN { printf ", multi-user.target %.1f s after the first journal line", b - a }'), whole script $(($(date +%s) - t_start)) s"
echo "== results in $out (check.log, summary.txt, journal.txt, candump.log, console.log); exit $rc"
exit "$rc"
