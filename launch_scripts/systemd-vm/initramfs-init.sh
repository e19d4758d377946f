#!/bin/busybox sh
# /init of the systemd VM's initramfs (launch_scripts/systemd-vm.sh): loads the modules the guest
# needs before its root exists (virtio block device, ext4, the 9p job share, CAN and vcan: they
# stay loaded after the switch), mounts the Debian root image read-write (qemu's snapshot=on keeps
# the image on the host unchanged) and hands over to systemd as PID 1. Never run on the host.
/bin/busybox mkdir -p /bin /proc /sys /dev /newroot
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc
mount -t devtmpfs devtmpfs /dev
mount -t sysfs sysfs /sys

fail() {
  echo "systemd-vm stage 1: $*" >/dev/console
  poweroff -f
}

for m in virtio_mmio virtio_blk crc32c_generic ext4 9p 9pnet_virtio virtio_console can can_raw can_dev vcan; do
  modprobe "$m" || fail "cannot load module $m"
done

# Devices probe asynchronously after the modules load: wait for the root disk.
try=0
until mount -t ext4 -o rw /dev/vda /newroot 2>/dev/null; do
  try=$((try + 1))
  [ "$try" -lt 300 ] || fail "cannot mount the root image (/dev/vda)"
  usleep 10000
done
[ -x /newroot/lib/systemd/systemd ] || fail "the root image has no /lib/systemd/systemd"
umount /sys /proc
umount /dev
exec switch_root /newroot /lib/systemd/systemd
