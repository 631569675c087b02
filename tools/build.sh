#!/usr/bin/env bash
# Configures and builds fogmap with a preset of CMakePresets.json; every binary lands in <dir>/bin/.
#   tools/build.sh [--demo] [--preset release|dev|tsan]
# release (default): build/, everything (services, fogctl, tests, benchmarks).
# --demo: only what `fogctl demo` runs (fogctl and the four services), the quick first build.
# dev: build-dev/, Debug with -Werror, AddressSanitizer and UBSan: the unit and service tests and
#   what they start (`ctest --preset dev` runs them).
# tsan: build-tsan/, ThreadSanitizer (tools/tsan.sh builds and runs what it needs).
set -euo pipefail
cd "$(dirname "$0")/.."

preset=release
target=
while [ $# -gt 0 ]; do
  case "$1" in
    --demo) target=demo; shift ;;
    --preset)
      [ $# -ge 2 ] || { echo "build.sh: --preset needs a value (release, dev or tsan)" >&2; exit 2; }
      preset=$2; shift 2 ;;
    -h | --help) sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "build.sh: unknown argument '$1' (try --help)" >&2; exit 2 ;;
  esac
done
case "$preset" in
  release | dev | tsan) ;;
  *) echo "build.sh: no preset '$preset' (release, dev or tsan)" >&2; exit 2 ;;
esac
[ "$preset" = dev ] && [ -z "$target" ] && target=unit-tests

# A new build directory is generated for Ninja where it is installed (tools/install-deps.sh): it
# compiles a target's units while the targets it links are still being built, where make waits
# for them; the demo build takes about 4 instead of 4.3 minutes on 2 cores. A directory keeps the
# generator it was made with.
binary_dir=build
[ "$preset" = release ] || binary_dir=build-$preset
generator=()
if [ ! -f "$binary_dir/CMakeCache.txt" ] && command -v ninja > /dev/null; then
  generator=(-G Ninja)
fi
cmake --preset "$preset" "${generator[@]}" > /dev/null
if [ -n "$target" ]; then
  cmake --build --preset "$preset" --target "$target" -j "$(nproc)"
else
  cmake --build --preset "$preset" -j "$(nproc)"
fi
