#!/bin/busybox sh
# /init of the vcan VM's initramfs (stage 1): loads what it takes to reach the host's filesystem,
# mounts the host's / read-only over virtio-9p under a tmpfs overlay, mounts the job share and
# switches into the host's root, where lbjob/stage2.sh (guest-run.sh) runs the command.
# Built into the initramfs by vcan-run.sh; never run on the host.
/bin/busybox mkdir -p /bin /sbin /proc /sys /dev /lower /rw /newroot
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc
mount -t devtmpfs devtmpfs /dev
mount -t sysfs sysfs /sys

fail() {
  echo "vcan-vm stage 1: $*" >/dev/console
  poweroff -f
}

for m in virtio_mmio virtio_pci 9p 9pnet_virtio overlay virtio_console; do
  modprobe "$m" || fail "cannot load module $m"
done

# Devices probe asynchronously after the modules load: wait for the shares to be mountable.
try=0
until mount -t 9p -o trans=virtio,version=9p2000.L,ro,cache=loose,msize=262144 hostroot /lower 2>/dev/null; do
  try=$((try + 1))
  [ "$try" -lt 200 ] || fail "cannot mount the host's root (9p tag hostroot)"
  usleep 10000
done
mount -t tmpfs -o size=512m tmpfs /rw
mkdir -p /rw/upper /rw/work
mount -t overlay overlay -o lowerdir=/lower,upperdir=/rw/upper,workdir=/rw/work /newroot ||
  fail "cannot mount the overlay root"
mkdir -p /newroot/lbjob
mount -t 9p -o trans=virtio,version=9p2000.L,cache=none,msize=262144 lbjob /newroot/lbjob ||
  fail "cannot mount the job share (9p tag lbjob)"
exec switch_root /newroot /bin/bash /lbjob/stage2.sh
