#!/usr/bin/env bash
# Lint: formatting and clang-tidy, the lint stage of launch_scripts/test.sh.
#   1. clang-format --dry-run -Werror over every C++ file of bridge/ tests/ bench/ fuzz/ that git
#      knows: a file that .clang-format would change fails the check.
#   2. clang-tidy (.clang-tidy) over the normal build's compile_commands.json, on
#      LINEBRIDGE_LINT_JOBS (2) cores, skipping units unchanged since a clean run (see below): the libraries' and programs' translation units (bridge/);
#      findings in our own headers and sources included from them count, generated code (build/)
#      does not. tests/ bench/ fuzz/ are format-checked only (see below for why).
#   launch_scripts/lint.sh [--format-only | --tidy-only] [--fix-format]
#     --fix-format   rewrite the files in place instead of checking (the tree-wide reformat)
#   LINEBRIDGE_BUILD_DIR (build): a configured build whose generated sources exist (test.sh's
#   build stage runs first). Cost on 2 cores: see docs/testing or the commit message.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
build=${LINEBRIDGE_BUILD_DIR:-build}
jobs=${LINEBRIDGE_LINT_JOBS:-2}
do_format=1 do_tidy=1 fix=0
for arg in "$@"; do
  case "$arg" in
    --format-only) do_tidy=0 ;;
    --tidy-only) do_format=0 ;;
    --fix-format) fix=1 do_tidy=0 ;;
    *) echo "lint.sh: unknown argument $arg" >&2; exit 2 ;;
  esac
done

status=0
if [ "$do_format" = 1 ]; then
  mapfile -t files < <(git ls-files -- bridge tests bench fuzz | grep -E '\.(cpp|hpp|h|cc)$')
  if [ "$fix" = 1 ]; then
    clang-format -i "${files[@]}"
    echo "lint.sh: formatted ${#files[@]} files"
  else
    t0=$SECONDS
    if ! printf '%s\0' "${files[@]}" | xargs -0 -n 20 -P "$jobs" clang-format --dry-run -Werror; then
      echo "lint.sh: formatting differs from .clang-format (fix: launch_scripts/lint.sh --fix-format)" >&2
      status=1
    fi
    echo "lint.sh: clang-format checked ${#files[@]} files in $((SECONDS - t0)) s"
  fi
fi

if [ "$do_tidy" = 1 ]; then
  [ -f "$build/compile_commands.json" ] || { echo "lint.sh: no $build/compile_commands.json (configure and build first)" >&2; exit 2; }
  # The translation units: the libraries' and programs' (bridge/: their unity batches, or the
  # sources when LINEBRIDGE_UNITY is off), not the generated message types (idl/). tests/ and
  # bench/ are format-checked only: tidying their 80 translation units (each parses Fast DDS and
  # gtest) would take most of half an hour on 2 cores. Headers under bridge/ tests/ bench/ fuzz/
  # that the units include are checked. The units are chosen by a regular expression on their path.
  units_re="^(?!.*/idl/)(.*/CMakeFiles/(lb_|linebridge).*|$root/bridge/.*)\$"
  t0=$SECONDS
  log=$(mktemp)
  # gcc-only warning flags from the build are not clang's: not an error for clang-tidy. A unit
  # whose preprocessed input, command, .clang-tidy and clang-tidy are those of an earlier clean
  # run is not tidied again (launch_scripts/clang_tidy_cached.py; LINEBRIDGE_TIDY_CACHE=0 turns
  # the cache off, a directory moves it): repeated runs on one machine re-tidy what changed.
  cache_arg=()
  [ -n "${LINEBRIDGE_TIDY_CACHE:-}" ] && cache_arg=(--cache "$LINEBRIDGE_TIDY_CACHE")
  if ! python3 launch_scripts/clang_tidy_cached.py --build "$build" --root "$root" --units "$units_re" \
    --jobs "$jobs" --header-filter "^$root/(bridge|tests|bench|fuzz)/" "${cache_arg[@]}" >"$log"; then status=1; fi
  findings=$(grep -cE '^/.*: (warning|error): ' "$log" || true)
  grep -E '^/.*: (warning|error): ' "$log" | sort -u | sed "s|^$root/||" || true
  echo "lint.sh: clang-tidy: $findings findings in $((SECONDS - t0)) s (the units: clang_tidy_cached's line above)"
  if [ "$findings" != 0 ]; then status=1; fi
  if [ "$status" != 0 ] && [ "$findings" = 0 ]; then tail -20 "$log" >&2; fi
  rm -f "$log"
fi
exit "$status"
