#!/usr/bin/env bash
# The folder map is enforced: the repository follows cmake/layers.cmake, and the checker refuses an
# include the map forbids (a pure library reaching into a service), naming the file and the folders.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cmake -DSOURCE_DIR="$root" -P "$root/cmake/check_layers.cmake"

scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
mkdir -p "$scratch/common/geometry" "$scratch/services/tracker" "$scratch/common/base"
printf '#pragma once\n' > "$scratch/services/tracker/tracker_node.hpp"
printf '#pragma once\n' > "$scratch/common/base/status.hpp"
printf '#include "common/base/status.hpp"\n#include <vector>\n' > "$scratch/common/geometry/ok.hpp"
cmake -DSOURCE_DIR="$scratch" -P "$root/cmake/check_layers.cmake" > /dev/null ||
  { echo "layers_test: an allowed include was refused" >&2; exit 1; }
printf '#include "common/base/status.hpp"\n#include "services/tracker/tracker_node.hpp"\n' > "$scratch/common/geometry/bad.cpp"
if out=$(cmake -DSOURCE_DIR="$scratch" -P "$root/cmake/check_layers.cmake" 2>&1); then
  echo "layers_test: a forbidden include passed" >&2
  exit 1
fi
grep -q 'common/geometry/bad.cpp: #include "services/tracker/tracker_node.hpp": common/geometry may not use services/tracker' <<< "$out" ||
  { echo "layers_test: the refusal does not name the include: $out" >&2; exit 1; }
echo "layers_test: the map holds, and a forbidden include is refused"
