#!/usr/bin/env bash
# Builds the Debian package (CPack) from a build directory and checks it with lintian.
#   launch_scripts/package.sh [BUILD_DIR]       (default: build; it must be configured and built)
# Prints the package's path on the last line. Exit status: 0 built and lintian found no error,
# 1 otherwise. lintian's tags are printed as they are (warnings and info do not fail).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-${LINEBRIDGE_BUILD_DIR:-build}}
[ -f "$build/CMakeCache.txt" ] || { echo "package: $build is not a configured build directory" >&2; exit 1; }
cmake --build "$build" --target linebridge linebridge-sim linebridge-cli linebridge-security debian_files >/dev/null
rm -f "$build"/linebridge_*.deb
(cd "$build" && cpack -G DEB >/dev/null)
deb=$(ls "$build"/linebridge_*.deb)
dpkg-deb --info "$deb" | sed -n '/Package:/,$p'
echo "== lintian"
# --tag-display-limit 0: every tag; errors fail the build (lintian's own exit status).
lintian --tag-display-limit 0 --info "$deb" && status=0 || status=$?
echo "$deb"
exit "$status"
