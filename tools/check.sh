#!/usr/bin/env bash
# Every check the project has, as the test command runs them (README), with each phase's time:
#   tools/check.sh [--fuzz-seconds N] [--serial]
#  1. the Release build (tools/build.sh);
#  2. the whole Release suite (ctest -j 2); behind it, the dev build (ASan and UBSan) and the
#     deployment's preparation (Docker, the base images, the image from build/);
#  3. the unit and service tests under the dev preset; behind them, the fuzz targets' build;
#  4. the fuzzers, N seconds each (tools/fuzz.sh, default 60);
#  5. the deployment end to end (tests/e2e/compose_test.sh --skip-without-docker).
# What runs behind runs at the idle CPU class (SCHED_IDLE, nice 19) and idle I/O class: the tests in
# front take a core whenever they want one, and the build takes what they leave (the Release suite
# spends much of its time waiting on processes, sockets and epochs). The tests are made to hold on
# a busy machine (tools/stress-suite.sh runs them beside two processes that burn both cores).
# --serial runs every phase alone, one after the other (to compare).
# Logs of what runs behind: build/check/. Stops at the first failure (and stops what runs behind),
# exit status that of the failed phase.
set -euo pipefail
cd "$(dirname "$0")/.."

fuzz_seconds=60
serial=0
while [ $# -gt 0 ]; do
  case "$1" in
    --fuzz-seconds)
      [[ "${2:-}" =~ ^[1-9][0-9]*$ ]] || { echo "check.sh: --fuzz-seconds takes a positive integer" >&2; exit 2; }
      fuzz_seconds=$2; shift 2 ;;
    --serial) serial=1; shift ;;
    -h | --help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "check.sh: unknown argument '$1' (try --help)" >&2; exit 2 ;;
  esac
done

logs=build/check
mkdir -p "$logs"
now() { date +%s; }
started=$(now)
table=()
record() {  # record NAME SECONDS
  table+=("$(printf '  %-58s %5d s' "$1" "$2")")
}
report() {
  echo "== tools/check.sh: phases"
  printf '%s\n' "${table[@]}"
  printf '  %-58s %5d s\n' "total" $(($(now) - started))
}

# Background jobs: each in its own session (setsid), so that a failure stops the whole job.
declare -A job_pid
behind() {  # behind NAME LOG COMMAND...: starts COMMAND behind, at idle priority
  local name=$1 log=$2
  shift 2
  local lower=(nice -n 19)
  # Each only where this system allows it (a container may not).
  chrt --idle 0 true 2> /dev/null && lower=(chrt --idle 0 "${lower[@]}")
  ionice -c 3 true 2> /dev/null && lower+=(ionice -c 3)
  if [ $serial -eq 1 ]; then
    lower=()
  fi
  echo "== behind: $name (log: $log)"
  rm -f "$log.seconds"
  # The job writes its own time when it ends (joined later, it may have ended long before).
  setsid "${lower[@]}" bash -c 'start=$(date +%s); "$@"; rc=$?; echo $(($(date +%s) - start)) > "$0"; exit $rc' \
    "$log.seconds" "$@" > "$log" 2>&1 &
  job_pid[$name]=$!
  if [ $serial -eq 1 ]; then join "$name" "$log"; fi
}
join() {  # join NAME LOG: waits for a background job; on failure shows its log's end and stops
  local name=$1 log=$2 status=0
  [ -n "${job_pid[$name]:-}" ] || return 0
  wait "${job_pid[$name]}" || status=$?
  record "$name (behind)" "$(cat "$log.seconds" 2> /dev/null || echo 0)"
  unset "job_pid[$name]"
  if [ $status -ne 0 ]; then
    echo "check.sh: FAILED: $name (exit $status); the end of $log:" >&2
    tail -n 40 "$log" >&2
    report
    exit $status
  fi
}
stop_behind() {
  local name
  for name in "${!job_pid[@]}"; do kill -- "-${job_pid[$name]}" 2> /dev/null || true; done
}
trap stop_behind EXIT

front() {  # front NAME COMMAND...: runs COMMAND in front and times it
  local name=$1 status=0 t0
  shift
  echo "== $name"
  t0=$(now)
  "$@" || status=$?
  record "$name" $(($(now) - t0))
  if [ $status -ne 0 ]; then
    echo "check.sh: FAILED: $name (exit $status)" >&2
    report
    exit $status
  fi
}

front "Release build" ./tools/build.sh
behind "dev build" "$logs/dev-build.log" ./tools/build.sh --preset dev
behind "deployment's images" "$logs/compose-prepare.log" ./tests/e2e/compose_test.sh --prepare --skip-without-docker
front "Release suite (ctest -j 2)" ctest --test-dir build --output-on-failure -j 2
join "dev build" "$logs/dev-build.log"
behind "fuzz build" "$logs/fuzz-build.log" ./tools/fuzz.sh --build-only
front "dev suite (ctest --preset dev)" ctest --preset dev
join "fuzz build" "$logs/fuzz-build.log"
front "fuzzers (${fuzz_seconds} s each)" ./tools/fuzz.sh --seconds "$fuzz_seconds"
join "deployment's images" "$logs/compose-prepare.log"
front "deployment (compose_test.sh)" ./tests/e2e/compose_test.sh --skip-without-docker
report
echo "check.sh: PASSED"
