#!/usr/bin/env bash
# The Debian package installed in a clean Debian 12 root and run there: builds the package
# (package.sh, with lintian), makes a minimal bookworm root with mmdebstrap from Debian's mirror
# (cached as a tarball), installs the package with apt (its dependencies come from the mirror),
# then, inside a private network namespace (DDS stays inside) and the root, runs the installed
# binaries: --version, --check of the shipped example, the simulator and the gateway on the demo
# line as the service user with no capabilities, the CLI reading a status sample, watching a bus,
# listing topics; the unit is checked with systemd-analyze; finally the package is purged.
#   launch_scripts/install-test.sh [BUILD_DIR]      (root; ~3-6 min the first time, then ~1-2 min)
# Needs mmdebstrap: launch_scripts/setup.sh --install-test installs it.
# Not part of test.sh (time budget): its output is quoted in the closing notes.
set -euo pipefail
cd "$(dirname "$0")/.."
root_dir=$PWD
build=${1:-${LINEBRIDGE_BUILD_DIR:-build}}
cache=${LINEBRIDGE_ROOT_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/linebridge-root}
mirror=${LINEBRIDGE_MIRROR:-http://deb.debian.org/debian}
[ "$(id -u)" -eq 0 ] || { echo "install-test: run as root (chroot, mounts)" >&2; exit 2; }
command -v mmdebstrap >/dev/null || { echo "install-test: mmdebstrap missing (launch_scripts/setup.sh --install-test installs it)" >&2; exit 2; }

step() { printf '\n== %s (%ss)\n' "$*" "$SECONDS"; }

step "package and lintian"
deb=$(./launch_scripts/package.sh "$build" | tail -n 1)
echo "$deb"

step "clean Debian 12 root"
mkdir -p "$cache"
tarball=$cache/bookworm-minbase.tar
if [ ! -s "$tarball" ]; then
  # The name must end in .tar for mmdebstrap to write a tarball (not a directory).
  mmdebstrap --quiet --variant=minbase --include=ca-certificates bookworm "$cache/partial.tar" "$mirror"
  mv "$cache/partial.tar" "$tarball"
fi
work=$(mktemp -d /tmp/linebridge-root.XXXXXX)
trap 'rm -rf "$work"' EXIT
target=$work/root
mkdir -p "$target"
tar -C "$target" -xf "$tarball"
cp "$deb" "$target/tmp/"
echo "root: $(du -sh "$target" | cut -f1) in $target"

# Inside a private mount namespace: /proc, /dev and /dev/shm of the root vanish with it.
in_root() {
  unshare -m --propagation private -- bash -c '
    set -e
    t=$1; shift
    mount -t proc proc "$t/proc"
    mount --rbind /dev "$t/dev"
    mount -t tmpfs -o size=256m tmpfs "$t/dev/shm"
    cp /etc/resolv.conf "$t/etc/resolv.conf" 2>/dev/null || true
    exec chroot "$t" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 "$@"
  ' in-root "$target" "$@"
}

step "apt-get install ./$(basename "$deb")"
in_root sh -c "apt-get -q update >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends /tmp/$(basename "$deb") | tail -n 3"
in_root dpkg -s linebridge | sed -n '1,/^Description/p'
in_root sh -c 'ls -l /usr/bin/linebridge* /usr/libexec/linebridge /lib/systemd/system/linebridge-bus.service /lib/systemd/system/linebridge-dds.service; ls -ld /etc/linebridge /etc/linebridge/line.yaml /var/lib/linebridge; id linebridge'

step "systemd-analyze (the installed unit)"
unit=$target/lib/systemd/system/linebridge-bus.service
systemd-analyze verify --root="$target" linebridge-bus.service linebridge-dds.service 2>&1 | grep -v 'Cannot add dependency job\|network-online' || true
systemd-analyze security --offline=true --root="$target" linebridge-dds.service 2>&1 | tail -n 3 || true
grep -E '^(Type|WatchdogSec|User|CapabilityBoundingSet|Restart|RestartPreventExitStatus)=' "$unit"

step "the installed binaries, in the root, inside a private network namespace"
./launch_scripts/netns-run.sh bash -c '
  set -e
  t=$1
  mount -t proc proc "$t/proc"
  mount --rbind /dev "$t/dev"
  mount -t tmpfs -o size=256m tmpfs "$t/dev/shm"
  exec chroot "$t" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root bash -c "
    set -e
    for b in linebridge linebridge-sim linebridge-cli linebridge-security; do \$b --version; done
    echo \"-- linebridge --check /etc/linebridge/line.yaml\"
    linebridge --check /etc/linebridge/line.yaml | tail -n 4
    demo=/usr/share/doc/linebridge/examples/demo.yaml
    linebridge-sim --config \$demo --duration 30 >/tmp/sim.log 2>&1 &
    sleep 1
    # The service user, no capabilities: what the unit gives the gateway.
    setpriv --reuid linebridge --regid linebridge --clear-groups --inh-caps=-all --bounding-set=-all \
      linebridge --config \$demo --duration 25 >/tmp/bridge.log 2>&1 &
    echo \"-- linebridge-cli echo saw1 status\"
    linebridge-cli --config \$demo echo saw1 status --duration 8 | head -n 2
    echo \"-- linebridge-cli echo bridge diagnostics\"
    linebridge-cli --config \$demo echo bridge diagnostics --duration 3 | head -n 8
    echo \"-- linebridge-cli candump extrusion --count 4\"
    linebridge-cli --config \$demo candump extrusion --count 4
    echo \"-- linebridge-cli topics (first 6)\"
    linebridge-cli --config \$demo topics --wait 2 | head -n 6
    wait
    echo \"-- gateway log (first 6 lines)\"
    head -n 6 /tmp/bridge.log
  "
' netns "$target"

step "apt-get purge linebridge"
in_root sh -c 'DEBIAN_FRONTEND=noninteractive apt-get purge -y -q linebridge | tail -n 2; id linebridge 2>&1 || true; ls -d /var/lib/linebridge /etc/linebridge 2>&1 || true'

step "done"
