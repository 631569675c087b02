#!/usr/bin/env bash
# Runs the test suite (or a part of it) N times on a busy machine: two CPU-burning processes run
# beside every ctest run, so tests that depend on the machine's speed fail here rather than now and
# then in CI. Prints per run whether it passed, the tests that failed and the time it took, then
# "K of N runs green". Exit status: 0 every run green, 1 a run failed, 2 bad usage.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
  cat <<'USAGE'
Usage: tools/stress-suite.sh [options] N [-- CTEST_ARGS...]

Runs `ctest --test-dir build --output-on-failure -j 2` N times while busy processes burn the CPU.

  N                  how many runs (a positive integer)
  -- CTEST_ARGS...   passed to every ctest run, e.g. -- -R 'HostileClient|ParentLink'
  --busy K           CPU-burning processes beside each run (default 2; 0 for none)
  --timeout S        ctest --timeout: seconds a test without its own TIMEOUT may take (default 900)
  --run-timeout S    a whole run is stopped after S seconds and counted as failed (default 3600)
  --logs DIR         keep each run's ctest output as DIR/run-I.log (default: a new temporary
                     directory; the logs of failed runs are kept, the others removed)
  --help             this text

The busy processes start before the first run and are killed when the script ends, however it
ends. Build first (tools/build.sh); the script only runs what build/ holds.
USAGE
}

runs=""
busy=2
test_timeout=900
run_timeout=3600
logs=""
ctest_args=()
needs_value() { [ $# -ge 2 ] || { echo "stress-suite.sh: $1 needs a value" >&2; exit 2; }; }
while [ $# -gt 0 ]; do
  case "$1" in
    --busy) needs_value "$@"; busy=$2; shift 2 ;;
    --timeout) needs_value "$@"; test_timeout=$2; shift 2 ;;
    --run-timeout) needs_value "$@"; run_timeout=$2; shift 2 ;;
    --logs) needs_value "$@"; logs=$2; shift 2 ;;
    -h | --help) usage; exit 0 ;;
    --) shift; ctest_args=("$@"); break ;;
    -*) echo "stress-suite.sh: unknown option '$1'" >&2; usage >&2; exit 2 ;;
    *)
      [ -z "$runs" ] || { echo "stress-suite.sh: one N only (got '$runs' and '$1')" >&2; exit 2; }
      runs=$1; shift ;;
  esac
done
[ -n "$runs" ] || { echo "stress-suite.sh: N is missing" >&2; usage >&2; exit 2; }
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "stress-suite.sh: N must be a positive integer, got '$runs'" >&2; exit 2; }
[[ "$busy" =~ ^[0-9]+$ ]] || { echo "stress-suite.sh: --busy takes a count, got '$busy'" >&2; exit 2; }
for value in "$test_timeout" "$run_timeout"; do
  [[ "$value" =~ ^[1-9][0-9]*$ ]] || { echo "stress-suite.sh: timeouts are positive seconds, got '$value'" >&2; exit 2; }
done
[ -d build ] || { echo "stress-suite.sh: no build/ (run tools/build.sh first)" >&2; exit 2; }
keep_all=1
if [ -z "$logs" ]; then
  logs=$(mktemp -d "${TMPDIR:-/tmp}/fogmap-stress.XXXXXX")
  keep_all=0
fi
mkdir -p "$logs"

burners=()
run_pid=""
stop_all() {
  local pid
  # The run first: timeout passes the signal on to ctest and the tests it started.
  if [ -n "$run_pid" ]; then
    kill -TERM "$run_pid" 2> /dev/null || true
    wait "$run_pid" 2> /dev/null || true
    run_pid=""
  fi
  for pid in "${burners[@]}"; do kill "$pid" 2> /dev/null || true; done
  for pid in "${burners[@]}"; do wait "$pid" 2> /dev/null || true; done
  burners=()
}
trap stop_all EXIT
trap 'stop_all; exit 130' INT
trap 'stop_all; exit 143' TERM
for ((b = 0; b < busy; ++b)); do
  bash -c 'while :; do :; done' &
  burners+=("$!")
done

echo "stress-suite.sh: $runs runs of ctest --test-dir build --output-on-failure -j 2 ${ctest_args[*]}" \
  "with $busy busy processes; logs in $logs"
green=0
for ((run = 1; run <= runs; ++run)); do
  log=$logs/run-$run.log
  start=$(date +%s.%N)
  status=0
  # In the background so that a signal to the script is handled at once (bash runs traps only
  # between foreground commands); wait returns when the run ends or a trap has stopped it.
  timeout --kill-after=30 "$run_timeout" \
    ctest --test-dir build --output-on-failure -j 2 --timeout "$test_timeout" --no-tests=error "${ctest_args[@]}" \
    > "$log" 2>&1 &
  run_pid=$!
  wait "$run_pid" || status=$?
  run_pid=""
  took=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.1f", e - s }')
  summary=$(grep -E '^[0-9]+% tests passed' "$log" | tail -1 || true)
  if [ $status -eq 0 ]; then
    green=$((green + 1))
    echo "run $run/$runs: PASS in ${took} s (${summary:-no summary})"
    [ $keep_all -eq 1 ] || rm -f "$log"
    continue
  fi
  if [ $status -eq 124 ] || [ $status -eq 137 ]; then
    echo "run $run/$runs: FAIL in ${took} s: the run took longer than --run-timeout ${run_timeout} s (log: $log)"
  else
    echo "run $run/$runs: FAIL in ${took} s (${summary:-ctest exit $status}; log: $log)"
  fi
  # ctest lists the failed tests after "The following tests FAILED:", one per line.
  sed -n '/^The following tests FAILED:/,$p' "$log" | grep -E '^[[:space:]]+[0-9]+ - ' |
    sed -E 's/^[[:space:]]+[0-9]+ - /  failed: /' || true
done
stop_all
[ $keep_all -eq 1 ] || rmdir "$logs" 2> /dev/null || true  # a temporary directory left empty
echo "$green of $runs runs green"
[ "$green" -eq "$runs" ] || exit 1
