#!/usr/bin/env bash
# The whole test suite from nothing: installs the dependencies (apt), builds with warnings as
# errors, runs every test (unit, integration over virtual buses with DDS in private network
# namespaces, real SocketCAN in a VM or natively), then runs the integration tests once more under
# ThreadSanitizer (LINEBRIDGE_TSAN=0 skips that stage), and builds the Debian package and checks
# it with lintian (LINEBRIDGE_PACKAGE=0 skips that; the clean-root install is install-test.sh).
#   launch_scripts/test.sh [extra ctest arguments, e.g. -R SawLine]
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

./launch_scripts/setup.sh
build=${LINEBRIDGE_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLINEBRIDGE_WERROR=ON
cmake --build "$build"

tsan_status=0
if [ "${LINEBRIDGE_TSAN:-1}" != 0 ]; then
  # Races between service calls, DDS threads and the bus loops are what this stage is for: the
  # real bridge and simulator processes, instrumented, under the integration tests.
  tsan="${build}-tsan"
  cmake -S . -B "$tsan" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLINEBRIDGE_WERROR=ON -DLINEBRIDGE_SANITIZE=thread
  cmake --build "$tsan" --target linebridge linebridge-sim integration_saw integration_core integration_monitor \
    integration_pdo integration_master_boot unit_sdo unit_pdo_transmitter unit_service_notifier
  echo "== ThreadSanitizer: integration tests"
  (cd "$tsan" && TSAN_OPTIONS="suppressions=$root/tests/tsan.supp second_deadlock_stack=1" \
    ctest --output-on-failure --timeout 300 -j 1 -R 'SawLine|CanopenCore|MonitorRole|PdoOverrides|MasterBoot|Transmitter|^Sdo|ServiceNotifier') ||
    tsan_status=$?
fi

package_status=0
if [ "${LINEBRIDGE_PACKAGE:-1}" != 0 ]; then
  echo "== Debian package and lintian"
  ./launch_scripts/package.sh "$build" || package_status=$?
fi

cd "$build"
ctest --output-on-failure --timeout 300 -j 2 "$@"
if [ "$package_status" != 0 ]; then
  echo "test.sh: the package stage failed (see above)" >&2
  exit "$package_status"
fi
if [ "$tsan_status" != 0 ]; then
  echo "test.sh: the ThreadSanitizer stage failed (see above)" >&2
  exit "$tsan_status"
fi
