#!/usr/bin/env bash
# Runs the SocketCAN test binaries where a real vcan0 exists (launch_scripts/vcan-run.sh: natively
# when the kernel has CAN, else in one VM boot), one after the other, and returns failure if any
# fails. ctest runs it as the test socketcan_vcan.
#   tests/socketcan/run-socketcan-tests.sh TEST_BINARY...
# LINEBRIDGE_SOCKETCAN_TESTS=skip: exit 77 (ctest: skipped). Nothing else skips: a runner that
# cannot be set up (no apt, no qemu) fails the test with its message.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
[ $# -ge 1 ] || { sed -n '2,8p' "$0" >&2; exit 2; }

if [ "${LINEBRIDGE_SOCKETCAN_TESTS:-}" = skip ]; then
  echo "socketcan tests skipped: LINEBRIDGE_SOCKETCAN_TESTS=skip"
  exit 77
fi

if [ "${1:-}" = --inside ]; then
  shift
  failed=()
  for t in "$@"; do
    echo "=== $(basename "$t")"
    start=$(date +%s.%N)
    # Output goes to the console as it comes; gtest's brief mode keeps it to failures and totals.
    if ! "$t" --gtest_brief=1; then failed+=("$(basename "$t")"); fi
    echo "=== $(basename "$t"): $(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.1f", e - s }') s"
  done
  if ((${#failed[@]})); then
    echo "socketcan: FAILED: ${failed[*]}"
    exit 1
  fi
  echo "socketcan: all passed"
  exit 0
fi

# sch_tbf: the full-transmit-queue test shapes a vcan with a token bucket.
exec "$root/launch_scripts/vcan-run.sh" --timeout 840 --modules sch_tbf -- "$0" --inside "$@"
