#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, AddressSanitizer + UBSan, -O1 -g) into build-fuzz/ and runs
# each on its seed corpus. fuzz/corpus/<target>/ is only read; what the run adds goes to
# build-fuzz/corpus/<target>/ (kept between runs). Any finding (crash, sanitizer report, leak,
# timeout, memory blow-up) leaves its input in build-fuzz/findings/<target>/, prints the command
# that replays it, and makes the script exit 1.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
  cat <<'EOF'
Usage: tools/fuzz.sh [--seconds N] [--target NAME] [--jobs N] [--build-only]

Builds the fuzz targets into build-fuzz/ and runs each for N seconds, as many side by side as
there are cores (FUZZ_PARALLEL=K: K at a time).

  --seconds N    seconds per target (default 60; the long run is --seconds 600)
  --target NAME  run only this target (default: all)
  --jobs N       fuzzing processes per target (default 1; more uses libFuzzer's -fork=N)
  --build-only   build the targets and stop (tools/check.sh builds them beside the dev tests)
  --help         this text

Targets: fuzz_kitti fuzz_nuscenes fuzz_pcd fuzz_upload fuzz_topology (fuzz/README.md).
Exit status: 0 no finding, 1 a finding (reproducers in build-fuzz/findings/<target>/),
2 bad usage or a failed build. The build uses $CMAKE_BUILD_PARALLEL_LEVEL jobs (default: all cores).
EOF
}

seconds=60
jobs=1
only=""
build_only=0
needs_value() { [ $# -ge 2 ] || { echo "fuzz.sh: $1 needs a value" >&2; exit 2; }; }
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) needs_value "$@"; seconds="$2"; shift 2 ;;
    --target) needs_value "$@"; only="$2"; shift 2 ;;
    --jobs) needs_value "$@"; jobs="$2"; shift 2 ;;
    --build-only) build_only=1; shift ;;
    --help | -h) usage; exit 0 ;;
    *) echo "fuzz.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
for value in "$seconds" "$jobs"; do
  [[ "$value" =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: --seconds and --jobs take a positive integer" >&2; exit 2; }
done

# Each target with the largest input it is given (bytes): above every seed, small enough to stay fast.
declare -A max_len=(
  [fuzz_kitti]=4096
  [fuzz_nuscenes]=5120
  [fuzz_pcd]=8192
  [fuzz_upload]=16384
  [fuzz_topology]=8192
)
targets=(fuzz_kitti fuzz_nuscenes fuzz_pcd fuzz_upload fuzz_topology)
if [ -n "$only" ]; then
  [ -n "${max_len[$only]+set}" ] || { echo "fuzz.sh: no target '$only' (${targets[*]})" >&2; exit 2; }
  targets=("$only")
fi

build=build-fuzz
command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ is missing (tools/install-deps.sh installs it)" >&2; exit 2; }
mkdir -p "$build/logs"
if ! cmake -S . -B "$build" -DFOGMAP_FUZZ=ON -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" >"$build/logs/configure.log" 2>&1; then
  cat "$build/logs/configure.log" >&2
  exit 2
fi
cmake --build "$build" -j "${CMAKE_BUILD_PARALLEL_LEVEL:-$(nproc)}" --target "${targets[@]}" || exit 2
[ "$build_only" -eq 0 ] || exit 0

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"

# One target: fuzzes it, then writes its summary line to $2 and exits 1 on a finding.
run_target() {
  local target=$1 summary_file=$2
  local corpus="$build/corpus/$target" findings="$build/findings/$target" log="$build/logs/$target.log"
  mkdir -p "$corpus" "$findings"
  local marker
  marker="$(mktemp)"
  local parallel=()
  [ "$jobs" -gt 1 ] && parallel=(-fork="$jobs")
  echo "fuzz.sh: $target for ${seconds}s (log: $log)"
  local status=0
  # The first directory takes the new inputs; the committed seeds are only read.
  "$build/bin/$target" "$corpus" "fuzz/corpus/$target" -max_total_time="$seconds" \
    -max_len="${max_len[$target]}" -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=10 \
    -artifact_prefix="$findings/" -print_final_stats=1 "${parallel[@]}" >"$log" 2>&1 || status=$?

  # Final stats, or (fork mode prints none) the last status line's count.
  local runs per_second inputs verdict
  runs="$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)"
  per_second="$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)"
  if [ -z "$runs" ]; then
    runs="$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#' || true)"
    [ -n "$runs" ] && per_second=$((runs / seconds))
  fi
  inputs="$(find "$corpus" "fuzz/corpus/$target" -type f | wc -l)"
  local new=()
  while IFS= read -r file; do new+=("$file"); done < <(find "$findings" -type f -newer "$marker" | sort)
  rm -f "$marker"

  local found_here=0
  if [ "$status" -eq 0 ] && [ ${#new[@]} -eq 0 ]; then
    verdict="nothing found"
  else
    found_here=1
    verdict="FINDING (exit $status)"
    {
      echo "fuzz.sh: $target found something:"
      grep -E 'ERROR: |SUMMARY: |runtime error|property violated|out-of-memory|Timeout|deadly signal' "$log" |
        head -8 | sed 's/^/    /' || true
      for file in "${new[@]}"; do echo "    reproduce: $build/bin/$target $file"; done
      [ ${#new[@]} -gt 0 ] || echo "    no reproducer was written; see $log"
    } >&2
  fi
  printf '%-14s runs %10s  (%s/s)  corpus %5s inputs  %s\n' "$target" "${runs:-?}" "${per_second:-?}" \
    "$inputs" "$verdict" >"$summary_file"
  return "$found_here"
}

# Targets run side by side, one per core ($FUZZ_PARALLEL to change it, with --jobs N each using N),
# each for its --seconds: on 2 cores the default run takes 3 minutes instead of 5.
parallel_targets="${FUZZ_PARALLEL:-$(( $(nproc) / jobs ))}"
[ "$parallel_targets" -ge 1 ] || parallel_targets=1
summaries="$(mktemp -d)"
found=0
running=0
for target in "${targets[@]}"; do
  if [ "$running" -ge "$parallel_targets" ]; then
    wait -n || found=1
    running=$((running - 1))
  fi
  run_target "$target" "$summaries/$target" &
  running=$((running + 1))
done
while [ "$running" -gt 0 ]; do
  wait -n || found=1
  running=$((running - 1))
done
summary=()
for target in "${targets[@]}"; do summary+=("$(cat "$summaries/$target" 2>/dev/null || echo "$target: no summary")"); done
rm -rf "$summaries"

echo
echo "fuzz.sh: ${seconds}s per target"
printf '  %s\n' "${summary[@]}"
exit "$found"
