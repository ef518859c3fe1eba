#!/usr/bin/env bash
# Configures and builds banmo-ceres into build/ (Release, Ninja).
# Arguments, if any, are the targets to build (default: everything).
#   bash tools/build.sh            # all: library, banmo, tests, benchmarks
#   bash tools/build.sh banmo      # only the executable
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_BUILD_DIR:-$root/build}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
targets=()
for t in "$@"; do targets+=(--target "$t"); done
cmake --build "$build" -j "${BANMO_JOBS:-$(nproc)}" "${targets[@]}"
