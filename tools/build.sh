#!/usr/bin/env bash
# Configures and builds fogmap (Release) into build/; every binary lands in build/bin/.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j "$(nproc)"
