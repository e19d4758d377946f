#!/usr/bin/env bash
# Runs a command where a real SocketCAN bus exists: a vcan0 interface, up, and no network.
#   launch_scripts/vcan-run.sh [OPTIONS] [--] COMMAND [ARGS...]
#   launch_scripts/vcan-run.sh --setup          # only prepare (install, download, build the VM)
# Returns the command's exit status; its stdout and stderr come out on this script's.
#
# Natively when this kernel has CAN (a line PC, an ordinary CI runner): `modprobe vcan`, then the
# command runs in a private network namespace (launch_scripts/netns-run.sh) with its own vcan0, so
# it can take the interface down or delete it without touching the host's. Otherwise (no AF_CAN,
# as on the development machines) inside a VM: Debian's own kernel booted by qemu in software
# emulation, the host's / shared read-only over virtio-9p with a tmpfs overlay, so host-built
# binaries, can-utils and python3-can run unchanged; the VM has no network interface at all.
#
# Options:
#   --native | --vm     force a mode (default: native when the kernel can create a vcan)
#   --timeout SECONDS   stop the command (or the VM) after this long: exit status 124 (default 1800)
#   --rw DIR            VM: DIR is shared read-write (changes reach the host); everything else is
#                       read-only with a throw-away overlay. Repeatable. Native mode ignores it.
#   --modules "M ..."   VM: extra kernel modules to load before the command (e.g. sch_netem)
#   --setup             prepare the VM (or check native CAN) and exit
# Environment:
#   LINEBRIDGE_VCAN_MODE=native|vm   same as --native / --vm
#   LINEBRIDGE_VM_CACHE=DIR          kernel, initramfs and modules cache
#                                    (default ${XDG_CACHE_HOME:-$HOME/.cache}/linebridge-vm)
#   LINEBRIDGE_VM_KERNEL=6.1.0-N-amd64  kernel to use (default: what linux-image-amd64 depends on,
#                                    resolved once and kept in the cache)
#   LINEBRIDGE_VM_APPEND="ARGS"      extra guest kernel arguments (e.g. tsc=reliable: a TSC
#                                    clocksource and high-resolution timers instead of jiffies)
#   Variables named LINEBRIDGE_*, GTEST_*, CTEST_* and SPDLOG_* are passed into the VM, as are
#   PATH, HOME, LANG and TERM.
# Exit status: the command's; 124 timeout; 125 the runner itself failed (message on stderr).
# Set-up goes through apt only (qemu-system-x86, busybox-static, xz-utils, and `apt-get download`
# of the kernel package, unpacked with dpkg -x into the cache): nothing on the host is changed
# beyond installing those packages. The first run takes about a minute; later runs reuse the cache.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
mode=${LINEBRIDGE_VCAN_MODE:-auto}
timeout_s=1800
rw_dirs=()
extra_modules=""
setup_only=0

die() {
  echo "vcan-run: $*" >&2
  exit 125
}
usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }

while [ $# -gt 0 ]; do
  case "$1" in
    --native) mode=native; shift ;;
    --vm) mode=vm; shift ;;
    --timeout) timeout_s=${2:?--timeout needs seconds}; shift 2 ;;
    --rw) rw_dirs+=("$(cd "${2:?--rw needs a directory}" && pwd)") || die "--rw $2: no such directory"; shift 2 ;;
    --modules) extra_modules=${2:?--modules needs a list}; shift 2 ;;
    --setup) setup_only=1; shift ;;
    -h|--help) usage; exit 0 ;;
    --) shift; break ;;
    -*) die "unknown option $1 (see --help)" ;;
    *) break ;;
  esac
done
[ "$setup_only" = 1 ] || [ $# -ge 1 ] || { usage >&2; exit 2; }

as_user=()
[ "$(id -u)" -eq 0 ] || as_user=(-r)

# True when this kernel can make a vcan and has raw CAN sockets (probed in a throw-away namespace).
native_can() {
  if command -v modprobe >/dev/null 2>&1; then
    modprobe -q vcan 2>/dev/null || true
    modprobe -q can-raw 2>/dev/null || true
  fi
  unshare "${as_user[@]}" -n sh -c \
    'ip link add dev lbprobe0 type vcan && grep -q CAN_RAW /proc/net/protocols' >/dev/null 2>&1
}

run_native() {
  local wrap
  # shellcheck disable=SC2016
  wrap='ip link show vcan0 >/dev/null 2>&1 || ip link add dev vcan0 type vcan || exit 125
        ip link set vcan0 up || exit 125
        exec "$@"'
  exec timeout -k 10 "$timeout_s" "$here/netns-run.sh" bash -c "$wrap" vcan-run "$@"
}

# --- VM set-up (cached) ---------------------------------------------------------------------------

cache=${LINEBRIDGE_VM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/linebridge-vm}

ensure_packages() {
  local missing=() p
  for p in qemu-system-x86 busybox-static xz-utils; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
  ((${#missing[@]})) || return 0
  [ "$(id -u)" -eq 0 ] || die "needs the packages ${missing[*]} (run launch_scripts/setup.sh as root)"
  echo "vcan-run: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  { apt-get install -y -q --no-install-recommends "${missing[@]}" ||
      { apt-get update -q && apt-get install -y -q --no-install-recommends "${missing[@]}"; }; } >&2 ||
    die "apt-get could not install ${missing[*]}"
}

kernel_version() {
  if [ -n "${LINEBRIDGE_VM_KERNEL:-}" ]; then
    echo "${LINEBRIDGE_VM_KERNEL#linux-image-}"
    return
  fi
  if [ -s "$cache/kernel" ]; then
    cat "$cache/kernel"
    return
  fi
  local dep
  dep=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
  if [ -z "$dep" ] && [ "$(id -u)" -eq 0 ]; then
    apt-get update -q >&2 || true
    dep=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
  fi
  [ -n "$dep" ] || die "apt knows no linux-image-amd64 (apt-get update?); or set LINEBRIDGE_VM_KERNEL"
  mkdir -p "$cache"
  echo "${dep#linux-image-}" >"$cache/kernel"
  echo "${dep#linux-image-}"
}

# Unpacks the kernel package into $kdir/root (no change to the host's /boot or /lib/modules) and
# indexes its modules; the .deb has no modules.dep.
ensure_kernel() {
  [ -f "$kdir/unpacked" ] && return 0
  local dl
  dl=$(mktemp -d)
  # apt downloads as its sandbox user, who must be able to write there.
  if [ "$(id -u)" -eq 0 ] && id _apt >/dev/null 2>&1; then chown _apt "$dl"; fi
  echo "vcan-run: downloading linux-image-$kver (apt-get download)" >&2
  (cd "$dl" && apt-get download -q "linux-image-$kver") >&2 ||
    { rm -rf "$dl"; die "apt-get download linux-image-$kver failed"; }
  rm -rf "$kdir/root"
  mkdir -p "$kdir"
  dpkg -x "$dl"/linux-image-"$kver"_*.deb "$kdir/root" || { rm -rf "$dl"; die "dpkg -x failed"; }
  rm -rf "$dl"
  /bin/busybox depmod -b "$kdir/root" "$kver" || die "depmod of the kernel's modules failed"
  touch "$kdir/unpacked"
}

# The uncompressed ELF boots 4-6 s faster under TCG than the bzImage (no in-guest decompression).
ensure_vmlinux() {
  [ -s "$kdir/vmlinux" ] && return 0
  local image offset
  image=$(echo "$kdir"/root/boot/vmlinuz-*)
  offset=$(LC_ALL=C grep -obUaP '\xFD7zXZ\x00' "$image" | head -n1 | cut -d: -f1)
  [ -n "$offset" ] || die "$image: no xz payload found"
  # xz stops after the first stream, so tail may die of SIGPIPE: only xz's status counts.
  { tail -c +"$((offset + 1))" "$image" || true; } | xz -dc --single-stream >"$kdir/vmlinux.tmp" ||
    die "cannot decompress $image"
  [ "$(head -c 4 "$kdir/vmlinux.tmp" | od -An -c | tr -d ' ')" = '177ELF' ] ||
    die "$image: the payload is not an ELF kernel"
  mv "$kdir/vmlinux.tmp" "$kdir/vmlinux"
}

# busybox + the stage-1 init + the modules needed to mount the shares; rebuilt when init changes.
ensure_initramfs() {
  local sum
  sum=$(cat "$here/vcan-vm/initramfs-init.sh" /bin/busybox | md5sum | cut -c1-12)
  initramfs="$kdir/initramfs-$sum.cpio"
  [ -s "$initramfs" ] && return 0
  local tree mods m dep
  tree=$(mktemp -d)
  mkdir -p "$tree/bin" "$tree/lib/modules/$kver"
  cp /bin/busybox "$tree/bin/busybox"
  cp "$here/vcan-vm/initramfs-init.sh" "$tree/init"
  chmod 755 "$tree/init"
  mods=$(awk -F: -v want=" virtio_mmio virtio_pci 9p 9pnet_virtio overlay virtio_console " '
    { n = $1; sub(/.*\//, "", n); sub(/\.ko$/, "", n); gsub(/-/, "_", n) }
    index(want, " " n " ") { print $1; print $2 }' "$kdir/root/lib/modules/$kver/modules.dep")
  for m in $mods; do
    mkdir -p "$tree/lib/modules/$kver/$(dirname "$m")"
    cp "$kdir/root/lib/modules/$kver/$m" "$tree/lib/modules/$kver/$m"
  done
  /bin/busybox depmod -b "$tree" "$kver" || die "depmod for the initramfs failed"
  (cd "$tree" && find . | /bin/busybox cpio -o -H newc >"$initramfs.tmp" 2>/dev/null) ||
    die "cannot build the initramfs"
  rm -rf "$tree"
  rm -f "$kdir"/initramfs-*.cpio
  mv "$initramfs.tmp" "$initramfs"
}

prepare_vm() {
  command -v flock >/dev/null || die "needs flock (util-linux)"
  ensure_packages
  kver=$(kernel_version)
  kdir="$cache/$kver"
  mkdir -p "$kdir"
  # One preparation at a time: parallel ctest runs share the cache.
  exec 9>"$kdir/lock"
  flock 9
  ensure_kernel
  ensure_vmlinux
  ensure_initramfs
  flock -u 9
  exec 9>&-
}

# --- VM run -----------------------------------------------------------------------------------------

run_vm() {
  local khz q
  job=$(mktemp -d "${TMPDIR:-/tmp}/vcan-run.XXXXXX")
  cleanup() {
    if [ -n "${out_pid:-}" ]; then kill "$out_pid" 2>/dev/null || true; fi
    if [ -n "${err_pid:-}" ]; then kill "$err_pid" 2>/dev/null || true; fi
    rm -rf "$job"
  }
  trap cleanup EXIT
  cp "$here/vcan-vm/guest-run.sh" "$job/stage2.sh"
  {
    printf 'kver=%q\nmodules_dir=%q\nextra_modules=%q\nrw_dirs=%q\n' \
      "$kver" "$kdir/root/lib/modules/$kver" "$extra_modules" "${rw_dirs[*]:-}"
  } >"$job/vm.conf"
  {
    echo 'set -e'
    local v
    for v in PATH HOME LANG TERM $(compgen -e | grep -E '^(LINEBRIDGE|GTEST|CTEST|SPDLOG)_' || true); do
      case "$v" in LINEBRIDGE_NETNS|LINEBRIDGE_VCAN_MODE) continue ;; esac
      [ -n "${!v+x}" ] && printf 'export %s=%q\n' "$v" "${!v}"
    done
    printf 'cd %q\n' "$PWD"
    echo 'set +e'
    printf 'exec'
    printf ' %q' "$@"
    echo
  } >"$job/command.sh"

  # The guest's TSC runs at the host's rate; without the hint the kernel hangs calibrating it.
  khz=$(awk -F: '/^cpu MHz/ { printf "%d", $2 * 1000; exit }' /proc/cpuinfo)
  [ -n "$khz" ] || khz=2000000

  mkfifo "$job/out.fifo" "$job/err.fifo"
  cat "$job/out.fifo" & out_pid=$!
  cat "$job/err.fifo" >&2 & err_pid=$!

  # shellcheck disable=SC2054  # qemu's options are comma-separated by design
  q=(qemu-system-x86_64
    -M microvm,x-option-roms=off,rtc=on,pit=on,pic=off,isa-serial=on,acpi=on
    -accel tcg,thread=multi -cpu max -m 1024 -smp 2
    -nodefaults -no-user-config -display none -nic none -no-reboot
    -kernel "$kdir/vmlinux" -initrd "$initramfs"
    -append "console=ttyS0 quiet cryptomgr.notests tsc_early_khz=$khz panic=-1${LINEBRIDGE_VM_APPEND:+ $LINEBRIDGE_VM_APPEND}"
    -serial "file:$job/console.log"
    -fsdev "local,id=hostroot,path=/,security_model=none,readonly=on,multidevs=remap"
    -device virtio-9p-device,fsdev=hostroot,mount_tag=hostroot
    -fsdev "local,id=lbjob,path=$job,security_model=none"
    -device virtio-9p-device,fsdev=lbjob,mount_tag=lbjob
    -device virtio-serial-device
    -chardev "file,id=out,path=$job/out.fifo" -device virtconsole,chardev=out
    -chardev "file,id=err,path=$job/err.fifo" -device virtconsole,chardev=err)
  local i=0 d
  for d in "${rw_dirs[@]}"; do
    q+=(-fsdev "local,id=lbrw$i,path=$d,security_model=none,multidevs=remap"
      -device "virtio-9p-device,fsdev=lbrw$i,mount_tag=lbrw$i")
    i=$((i + 1))
  done

  local qrc=0
  timeout -k 10 "$timeout_s" "${q[@]}" </dev/null >"$job/qemu.log" 2>&1 || qrc=$?
  wait "$out_pid" 2>/dev/null || true
  wait "$err_pid" 2>/dev/null || true
  out_pid="" err_pid=""
  if [ -s "$job/rc" ]; then
    return "$(cat "$job/rc")"
  fi
  if [ "$qrc" = 124 ]; then
    echo "vcan-run: timed out after ${timeout_s}s (VM stopped)" >&2
    return 124
  fi
  {
    echo "vcan-run: the VM stopped without an exit status (qemu exit $qrc)"
    echo "--- qemu ---"; tail -n 20 "$job/qemu.log"
    echo "--- console ---"; tail -n 40 "$job/console.log"
  } >&2
  return 125
}

# --- main ---------------------------------------------------------------------------------------------

if [ "$mode" = auto ]; then
  if native_can; then mode=native; else mode=vm; fi
fi
case "$mode" in
  native)
    native_can || die "native mode: this kernel cannot create a vcan interface (modprobe vcan?)"
    if [ "$setup_only" = 1 ]; then echo "vcan-run: native SocketCAN available"; exit 0; fi
    run_native "$@"
    ;;
  vm)
    prepare_vm
    if [ "$setup_only" = 1 ]; then echo "vcan-run: VM ready (kernel $kver, cache $kdir)"; exit 0; fi
    rc=0
    run_vm "$@" || rc=$?
    exit "$rc"
    ;;
  *) die "LINEBRIDGE_VCAN_MODE must be native or vm, not '$mode'" ;;
esac
