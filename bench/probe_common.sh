# Sourced by the issue-27 probe scripts (probe_boot_memory.sh, probe_memory_load.sh,
# heaptrack_split.sh): the options they share and their re-run inside a private network namespace
# (every DDS participant runs in one: docs/testing.md). Needs `root` set by the caller.

# probe_option NAME VALUE: takes one of the shared options into its variable (buses, devices,
# profiles, build_dir, out); false for any other, which the caller parses.
probe_option() {
  case "$1" in
    --buses) buses=$2 ;;
    --devices) devices=$2 ;;
    --profiles-file) profiles=$(realpath -m "$2") ;;
    --build-dir) build_dir=$(realpath -m "$2") ;;
    --out) out=$(realpath -m "$2") ;;
    *) return 1 ;;
  esac
}

# The calling script's opening comment.
probe_usage() { sed -n '2,/^set -euo/p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'; }

# probe_in_netns TEMP_PREFIX ARGS...: outside a namespace, runs the script again in a new one with
# its arguments, its build directory and an output directory (a new /tmp/TEMP_PREFIX.* when none).
probe_in_netns() {
  local prefix=$1
  shift
  [ "${LINEBRIDGE_NETNS:-}" != 1 ] || return 0
  [ -n "$out" ] || out=$(mktemp -d "/tmp/$prefix.XXXXXX")
  mkdir -p "$out"
  exec "$root/launch_scripts/netns-run.sh" "$0" "$@" --build-dir "$build_dir" --out "$out"
}
