#!/usr/bin/env bash
# Makes docs/status-page.png: the status page of the running demo line (its simulators and the
# bridge, inside a private network namespace), as headless chromium renders it at 1280x900 once
# every device is online.
#   launch_scripts/status-page-screenshot.sh [OUTPUT.png]     (default: docs/status-page.png)
# Needs chromium (launch_scripts/setup.sh installs it). Builds linebridge and linebridge-sim in
# ${LINEBRIDGE_BUILD_DIR:-build} first.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ -z "${inside:-}" ]; then
  out=$(realpath -m "${1:-docs/status-page.png}")
  command -v chromium >/dev/null || { echo "status-page-screenshot: no chromium (launch_scripts/setup.sh)" >&2; exit 2; }
  build=${LINEBRIDGE_BUILD_DIR:-build}
  [ -f "$build/build.ninja" ] || cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$build" --target linebridge linebridge-sim
  exec env inside=1 out="$out" LINEBRIDGE_BIN="$PWD/$build/bridge/app" ./launch_scripts/netns-run.sh "$0"
fi

# --- inside the private namespace: the built-in demo line, its page on 127.0.0.1:9420 ---
bin=${LINEBRIDGE_BIN:?}
work=$(mktemp -d /tmp/linebridge-screenshot.XXXXXX)
pids=()
cleanup() {
  local p
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT

"$bin/linebridge-sim" >"$work/sim.log" 2>&1 & pids+=($!)
"$bin/linebridge" >"$work/bridge.log" 2>&1 & pids+=($!)

# The page, fetched over a plain socket (bash's /dev/tcp: nothing else to install).
page() {
  exec 3<>/dev/tcp/127.0.0.1/9420 || return 1
  printf 'GET / HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n' >&3
  cat <&3
  exec 3>&-
}
online=0
for _ in $(seq 1 60); do
  online=$(page 2>/dev/null | grep -o '>ONLINE<' | wc -l || true)
  [ "$online" -ge 4 ] && break
  sleep 0.5
done
if [ "$online" -lt 4 ]; then
  echo "status-page-screenshot: the demo's four devices never showed online; bridge log:" >&2
  cat "$work/bridge.log" >&2
  exit 1
fi
sleep 3  # a few diagnostics more: load and SYNC figures over whole seconds

# --no-sandbox: inside the namespace's user namespace chromium's sandbox cannot be set up;
# its own profile and HOME: nothing of the machine's.
HOME="$work" chromium --headless=new --no-sandbox --disable-gpu --hide-scrollbars --user-data-dir="$work/profile" \
  --window-size=1280,900 --screenshot="$out" http://127.0.0.1:9420/ 2>"$work/chromium.log" >/dev/null ||
  { cat "$work/chromium.log" >&2; exit 1; }
echo "status-page-screenshot: $out"
