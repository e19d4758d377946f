#!/bin/bash
# shellcheck disable=SC2154  # kver, modules_dir, extra_modules, rw_dirs: from lbjob/vm.conf
# Stage 2 of the vcan VM, running on the host's filesystem (read-only, tmpfs overlay) as PID 1:
# mounts the kernel filesystems, loads CAN, brings up loopback (multicast routed to it, as
# netns-run.sh does) and vcan0, runs the job's command with its output on the two virtio consoles,
# writes the exit status to the job share and powers off. vcan-run.sh copies it to lbjob/stage2.sh.
set -uo pipefail
job=/lbjob
# shellcheck source=/dev/null
. "$job/vm.conf"  # kver, modules_dir, rw_dirs (written by vcan-run.sh)

finish() {
  echo "$1" >"$job/rc.tmp" && mv "$job/rc.tmp" "$job/rc"
  sync
  # poweroff -f asks ACPI; the sysrq path stops the machine when that is not there.
  /bin/busybox poweroff -f
  echo o >/proc/sysrq-trigger
  sleep 10
}

setup() {
  mount -t proc proc /proc &&
    mount -t sysfs sysfs /sys &&
    mount -t devtmpfs devtmpfs /dev || return 1
  mkdir -p /dev/pts /dev/shm
  mount -t devpts devpts /dev/pts
  mount -t tmpfs -o size=512m tmpfs /dev/shm
  mount -t tmpfs tmpfs /run
  # The kernel's own module tree (the cache's copy of the .deb), for modprobe of anything a test needs.
  mkdir -p "/lib/modules/$kver"
  mount --bind "$modules_dir" "/lib/modules/$kver" || return 1
  local m
  for m in can can_raw can_dev vcan ${extra_modules:-}; do
    /bin/busybox modprobe "$m" || { echo "vcan-vm: cannot load module $m" >&2; return 1; }
  done
  local i=0 d
  for d in ${rw_dirs:-}; do
    mkdir -p "$d"  # it may lie under a tmpfs mounted above (/tmp)
    mount -t 9p -o trans=virtio,version=9p2000.L,cache=none,msize=262144 "lbrw$i" "$d" ||
      { echo "vcan-vm: cannot mount $d read-write" >&2; return 1; }
    i=$((i + 1))
  done
  hostname linebridge-vm
  ip link set lo up &&
    ip link set lo multicast on &&
    ip route add 224.0.0.0/4 dev lo src 127.0.0.1 &&
    ip link add dev vcan0 type vcan &&
    ip link set vcan0 up
}

exec </dev/null
if ! setup >"$job/setup.log" 2>&1; then
  cat "$job/setup.log" >/dev/console
  finish 125
fi
exec >/dev/hvc0 2>/dev/hvc1
# The VM has no network at all: DDS participants are as contained here as in netns-run.sh.
export LINEBRIDGE_NETNS=1 LINEBRIDGE_IN_VM=1
bash "$job/command.sh"
finish $?
