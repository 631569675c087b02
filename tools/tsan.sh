#!/usr/bin/env bash
# ThreadSanitizer over the threaded parts: the merge-aggregator (core, ingest, emitter, global-map
# service), the tracker service, the client links (parent link, tracker link) and the integration
# tests that run them as real processes. Builds with g++ -fsanitize=thread -O2 -g into build-tsan/
# (services and tests), runs the chosen tests with every service process instrumented too, and
# counts the reports (CMakePresets.json, preset tsan). Exit status: 0 no report, 1 reports (listed in build-tsan/tsan-logs/), 2 bad
# usage or a failed build.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
  cat <<'USAGE'
Usage: tools/tsan.sh [--tests REGEX] [--no-build]

Builds fogmap with ThreadSanitizer into build-tsan/ and runs the threaded tests under it.

  --tests REGEX  ctest -R pattern (default: the aggregator service, tracker service, link and
                 start-up and stop helpers, and integration tests: AggregatorService|
                 AggregatorProcess|TlsService|TrackerService|TrackerNode|TrackerTicker|ParentLink|
                 DetectionLink|CentroidLink|GlobalMapFeed|Broadcaster|Periodic|RunService|
                 ServeUntilStopped|StopSignals.|StopRequest|StreamFollow|EdgeProcess|Cluster.|
                 HostileClient|Shutdown)
  --no-build     run what build-tsan/ holds
  --help         this text

Reports go to build-tsan/tsan-logs/<process>.<pid>; the summary counts them. The instrumented
services run 5 to 15 times slower, so the tests whose oracle needs complete epochs stretch their
schedule by FOGMAP_TEST_TIME_SCALE (default here 6; tests/support/time_scale.hpp).
USAGE
}

tests='AggregatorService|AggregatorProcess|TlsService|TrackerService|TrackerNode|TrackerTicker|ParentLink|DetectionLink|CentroidLink|GlobalMapFeed|Broadcaster|Periodic|RunService|ServeUntilStopped|StopSignals\.|StopRequest|StreamFollow|EdgeProcess|Cluster\.|HostileClient|Shutdown'
build=1
while [ $# -gt 0 ]; do
  case "$1" in
    --tests) [ $# -ge 2 ] || { echo "tsan.sh: --tests needs a value" >&2; exit 2; }; tests=$2; shift 2 ;;
    --no-build) build=0; shift ;;
    -h | --help) usage; exit 0 ;;
    *) echo "tsan.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done

dir=build-tsan
# Third-party reports only (tools/tsan.supp says which and why); the build runs the test binaries
# to list their tests, so it needs them too.
supp=$PWD/tools/tsan.supp
export TSAN_OPTIONS="suppressions=$supp"
if [ $build -eq 1 ]; then
  cmake --preset tsan > /dev/null ||
    { echo "tsan.sh: configure failed" >&2; exit 2; }
  cmake --build "$dir" -j "$(nproc)" --target merge-aggregator edge-cluster tracker detection fogctl \
    fogmap_aggregator_tests fogmap_service_tests fogmap_tracker_service_tests fogmap_edge_tests fogmap_integration_tests ||
    { echo "tsan.sh: build failed" >&2; exit 2; }
fi
logs=$PWD/$dir/tsan-logs
rm -rf "$logs"
mkdir -p "$logs"
# Every process the tests start inherits this: one log file per process, all reports kept.
export TSAN_OPTIONS="suppressions=$supp log_path=$logs/tsan halt_on_error=0 second_deadlock_stack=1 history_size=4"
export FOGMAP_TEST_TIME_SCALE=${FOGMAP_TEST_TIME_SCALE:-6}
status=0
ctest --test-dir "$dir" -R "$tests" --output-on-failure -j 2 --timeout 900 || status=$?
reports=$(cat "$logs"/tsan.* 2> /dev/null | grep -c '^WARNING: ThreadSanitizer' || true)
echo "tsan.sh: $reports ThreadSanitizer reports (logs: $dir/tsan-logs/); ctest exit $status"
if [ "$reports" -gt 0 ]; then
  grep -h -A3 '^WARNING: ThreadSanitizer' "$logs"/tsan.* | head -40
  exit 1
fi
[ $status -eq 0 ] || exit 1
