#!/usr/bin/env bash
# CI under load (issue 26, deliverable 7): does `.ci/run` hold while another process keeps every
# core busy? Clones this repository's HEAD into $CI_LOAD_WORK/ci-under-load-clone, emptied first
# (a clean clone, as CI sees it), starts `stress-ng --cpu <cores>` (Debian's stress-ng, installed with apt if missing)
# in the background, runs `.ci/run` in the clone N times in a row, records each run's exit code,
# wall time and test.sh's stage times, stops stress-ng and prints a summary table.
#
#   launch_scripts/ci-under-load.sh [--runs N] [--once] [--cpu K] [--keep] [-- extra args for test.sh]
#     --runs N   runs in a row (default 3: the issue's "passes three times in a row")
#     --once     one run (same as --runs 1)
#     --cpu K    stress-ng CPU workers (default: the number of cores, `nproc`)
#     --keep     keep the clone and the logs (default: keep only the logs)
#     -- ...     extra arguments for launch_scripts/test.sh's stage 4 (ctest), e.g. -- -R SawLine
#   Environment: every LINEBRIDGE_* variable is passed through to the runs, so a quick check is
#     LINEBRIDGE_TSAN=0 LINEBRIDGE_ASAN=0 LINEBRIDGE_PACKAGE=0 launch_scripts/ci-under-load.sh --once -- -R SimConformance
#   A full run (3 x .ci/run on 2 loaded cores) takes about 2 hours.
#   CI_LOAD_WORK (/tmp): where the clone goes. Exit status: 0 when every run passed, 1 otherwise. Logs: $CI_LOAD_LOGS (default
#   /tmp/ci-under-load.<date>/run-<i>.log), one per run, and summary.txt.
#
# .ci/run is exactly the README's test command; when extra arguments are given this script calls
# ./launch_scripts/test.sh with them instead (the same thing .ci/run runs, plus the arguments).
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD

runs=3
cpu=$(nproc)
keep=0
extra=()
while (($#)); do
  case "$1" in
    --runs) runs=$2; shift 2 ;;
    --once) runs=1; shift ;;
    --cpu) cpu=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    --) shift; extra=("$@"); break ;;
    -h | --help) sed -n '2,22p' "$0"; exit 0 ;;
    *) echo "ci-under-load: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "ci-under-load: --runs wants a positive number" >&2; exit 2; }

if ! command -v stress-ng >/dev/null; then
  echo "ci-under-load: installing stress-ng (apt)"
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -q
  "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends stress-ng
fi

logs=${CI_LOAD_LOGS:-/tmp/ci-under-load.$(date -u +%Y%m%dT%H%M%SZ)}
mkdir -p "$logs"
mkdir -p "${CI_LOAD_WORK:-/tmp}"
# One fixed clone directory, so that a compiler cache (test.sh uses ccache when the machine has it)
# finds the objects of an earlier invocation: the tests are compiled with the absolute paths of
# the programs they start, which differ from one directory to the next. A lock keeps two
# invocations out of each other's clone.
work="${CI_LOAD_WORK:-/tmp}/ci-under-load-clone"
exec 9>"${CI_LOAD_WORK:-/tmp}/ci-under-load.lock"
flock -n 9 || { echo "ci-under-load: another run holds ${CI_LOAD_WORK:-/tmp}/ci-under-load.lock" >&2; exit 2; }
rm -rf "$work"
mkdir -p "$work"
head=$(git rev-parse HEAD)
git clone -q --no-hardlinks "$repo" "$work/linebridge"
git -C "$work/linebridge" checkout -q "$head"
echo "ci-under-load: HEAD $head cloned to $work/linebridge; logs in $logs"

stress_pid=
stop_stress() {
  if [ -n "$stress_pid" ] && kill -0 "$stress_pid" 2>/dev/null; then
    kill "$stress_pid" 2>/dev/null || true
    wait "$stress_pid" 2>/dev/null || true
  fi
  stress_pid=
}
cleanup() {
  stop_stress
  if [ "$keep" = 0 ]; then rm -rf "$work"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# stress-ng's own timeout is a safety net only (the trap stops it): 12 h.
stress-ng --cpu "$cpu" --timeout 43200 --quiet &
stress_pid=$!
echo "ci-under-load: stress-ng --cpu $cpu (pid $stress_pid) keeps the cores busy"

declare -a codes walls stages
all_ok=1
for ((i = 1; i <= runs; i++)); do
  log="$logs/run-$i.log"
  echo "ci-under-load: run $i of $runs (log $log)"
  t0=$SECONDS
  code=0
  if ((${#extra[@]})); then
    (cd "$work/linebridge" && ./launch_scripts/test.sh "${extra[@]}") >"$log" 2>&1 || code=$?
  else
    (cd "$work/linebridge" && ./.ci/run) >"$log" 2>&1 || code=$?
  fi
  codes[i]=$code
  walls[i]=$((SECONDS - t0))
  stages[i]=$(grep -o 'test.sh: stage times: .*' "$log" | tail -1 | sed 's/test.sh: stage times: //')
  [ -n "${stages[i]}" ] || stages[i]="(no stage times: see the log)"
  [ "$code" = 0 ] || all_ok=0
  echo "ci-under-load: run $i exit $code after ${walls[i]} s"
  # Each run starts from the clean clone: the next run builds from nothing, as CI does.
  if ((i < runs)); then git -C "$work/linebridge" clean -qfdx; fi
done
stop_stress

{
  echo "ci-under-load: $runs run(s) of $([ ${#extra[@]} -gt 0 ] && echo "launch_scripts/test.sh ${extra[*]}" || echo .ci/run) on $head, stress-ng --cpu $cpu"
  env | grep '^LINEBRIDGE_' | sed 's/^/  env: /' || true
  printf '%-4s %-5s %-9s %s\n' run exit "wall" "stage times"
  for ((i = 1; i <= runs; i++)); do
    printf '%-4s %-5s %-9s %s\n' "$i" "${codes[i]}" "$((walls[i] / 60))m$((walls[i] % 60))s" "${stages[i]}"
  done
  grep -h 'test.sh: failed stages\|^ *[0-9]* - .*(Failed\|Timeout\|SEGFAULT)' "$logs"/run-*.log | sed 's/^/  /' || true
} | tee "$logs/summary.txt"
[ "$all_ok" = 1 ]
