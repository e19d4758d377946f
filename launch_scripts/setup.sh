#!/usr/bin/env bash
# Installs every build and run dependency of linebridge from Debian's packages.
# Idempotent: installs only what is missing, so repeated runs cost a dpkg query. clang-format and
# clang-tidy (14) are for the lint stage (launch_scripts/lint.sh); lld links every build (CMakeLists.txt).
# gdb: a test that finds a thread stuck prints every thread's stack (tests/support/thread_stacks.hpp).
# libcivetweb-dev, prometheus-cpp-dev: the DDS process's status page and metrics (docs/observability.md);
# chromium: the status page's test renders it in a real browser (headless); prometheus: the real
# server and promtool the metrics, dashboard and alert-rule tests check against.
#   launch_scripts/setup.sh [--clang] [--install-test]
#     --clang: also clang and its sanitizer/libFuzzer runtime, for the AddressSanitizer + UBSan and
#              fuzz stages (fuzz/)
#     --install-test: also mmdebstrap, which launch_scripts/install-test.sh makes its clean Debian 12
#              root with
#     --list: print the packages these options stand for, one a line, and install nothing
set -euo pipefail

packages=(
  build-essential cmake pkg-config ninja-build
  libfastrtps-dev libfastcdr-dev fastddsgen fastdds-tools
  libyaml-cpp-dev libspdlog-dev libfmt-dev libgtest-dev libcli11-dev
  iproute2 util-linux procps
  can-utils qemu-system-x86 busybox-static xz-utils
  openssl libssl-dev libtinyxml2-dev
  libsystemd-dev dpkg-dev fakeroot lintian
  libcivetweb-dev prometheus-cpp-dev chromium prometheus
  clang-format clang-tidy lld
  gdb
)
list=0
for arg in "$@"; do
  case "$arg" in
    --list) list=1 ;;
    --clang) packages+=(clang libclang-rt-14-dev) ;;
    --install-test) packages+=(mmdebstrap) ;;
    *) echo "setup: unknown argument $arg (--clang, --install-test, --list)" >&2; exit 2 ;;
  esac
done
if ((list)); then
  printf '%s\n' "${packages[@]}"
  exit 0
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done

if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -q
  "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "setup: all dependencies present"
fi
