#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/, clang with AddressSanitizer and UndefinedBehaviorSanitizer)
# and runs each, one after the other, from its committed seed corpus (fuzz/corpus/<target>/).
#   launch_scripts/fuzz.sh [--runs N | --seconds S] [--timeout S] [--nice N] [target ...]
#                          (default: every target, --runs 10000000, --timeout 10, --nice 19)
# The long run: launch_scripts/fuzz.sh (at nice 19, so that it yields to other work; hours on 2
# cores). test.sh runs --seconds 5 --nice 0: a 5-s limit is wall time, and at nice 19 beside a
# busy machine most of it went to loading the seeds (seen: 3 inputs in 21 s).
# --timeout is libFuzzer's per-input limit in wall-clock seconds: a fuzzer at nice 19 beside a
# build can be kept off the CPU for longer than 10 s, which libFuzzer reports as a timeout (seen:
# a profile input that runs in 1.6 s alone); a long run beside other work takes --timeout 120.
# Each target works on a copy of its seeds in $build/fuzz-corpus/<target>, keeps its log in
# $build/fuzz-logs/<target>.log and any crashing input in $build/fuzz-artifacts/<target>/.
# Exit 0 when every target ran to its limit without a finding, 1 on any finding, 130 when one
# was interrupted (SIGINT) and none found anything. Reproduce a finding: $build/fuzz/fuzz_<target> <file>.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

limit=(-runs=10000000)
timeout=10
niceness=19
targets=()
while (($#)); do
  case "$1" in
    --runs) limit=("-runs=$2"); shift 2 ;;
    --seconds) limit=("-max_total_time=$2"); shift 2 ;;
    --timeout) timeout=$2; shift 2 ;;
    --nice) niceness=$2; shift 2 ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
if ((${#targets[@]} == 0)); then
  for f in fuzz/fuzz_*.cpp; do t=${f#fuzz/fuzz_}; targets+=("${t%.cpp}"); done
fi

./launch_scripts/setup.sh --clang >/dev/null
build=${LINEBRIDGE_FUZZ_BUILD_DIR:-build-fuzz}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DLINEBRIDGE_FUZZ=ON -DLINEBRIDGE_SANITIZE=address,undefined >/dev/null
cmake --build "$build" --target "${targets[@]/#/fuzz_}"

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
failed=()
interrupted=()
for t in "${targets[@]}"; do
  corpus="$build/fuzz-corpus/$t" artifacts="$build/fuzz-artifacts/$t/" log="$build/fuzz-logs/$t.log"
  mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
  maxlen=4096
  [ "$t" = profile ] && maxlen=16384  # the seeds are the built-in profiles
  args=("-timeout=$timeout" -rss_limit_mb=2560 "-max_len=$maxlen" -print_final_stats=1 "-artifact_prefix=$artifacts")
  [ -f "fuzz/$t.dict" ] && args+=("-dict=fuzz/$t.dict")
  echo "== fuzz $t (${limit[*]})"
  status=0
  # The seeds are read, never written: new inputs go to the working corpus.
  nice -n "$niceness" "$build/fuzz/fuzz_$t" "${args[@]}" "${limit[@]}" "$corpus" "$root/fuzz/corpus/$t" >"$log" 2>&1 || status=$?
  grep -E '^#[0-9]+\s+DONE|^Done [0-9]+ runs|^stat::number_of_executed_units|^stat::average_exec_per_sec' "$log" || true
  # 72 with libFuzzer's own words: stopped by SIGINT (Ctrl-C, a stopped lane), not a finding.
  if [ "$status" = 72 ] && grep -q 'libFuzzer: run interrupted' "$log"; then
    echo "fuzz.sh: $t interrupted (no finding; the counts above are where it stopped)" >&2
    interrupted+=("$t")
    continue
  fi
  if [ "$status" != 0 ]; then
    failed+=("$t")
    echo "fuzz.sh: $t found a problem (exit $status); the report:" >&2
    grep -E -A30 '^==[0-9]+==ERROR|runtime error|^SUMMARY|deadly signal|Test unit written' "$log" | head -60 >&2 || tail -40 "$log" >&2
  fi
done
if ((${#failed[@]})); then
  echo "fuzz.sh: findings in: ${failed[*]} (inputs in $build/fuzz-artifacts/)" >&2
  exit 1
fi
if ((${#interrupted[@]})); then
  echo "fuzz.sh: no findings; interrupted before their limit: ${interrupted[*]}" >&2
  exit 130
fi
echo "fuzz.sh: ${#targets[@]} targets, no findings"
