#!/usr/bin/env bash
# The whole test suite from nothing: installs the dependencies (apt), builds with warnings as
# errors, runs every test. Tests that start DDS run in private network namespaces (netns-run.sh).
#   launch_scripts/test.sh [extra ctest arguments, e.g. -R SawLine]
set -euo pipefail
cd "$(dirname "$0")/.."

./launch_scripts/setup.sh
build=${LINEBRIDGE_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLINEBRIDGE_WERROR=ON
cmake --build "$build"
cd "$build"
ctest --output-on-failure --timeout 300 -j 2 "$@"
