#!/usr/bin/env bash
# Configures and builds banmo-ceres into build/ (Release, Ninja). Warnings in
# the project's own code are errors (BANMO_WERROR=OFF in the environment turns
# that off, e.g. to try a newer compiler).
# Arguments, if any, are the targets to build (default: everything).
#   bash tools/build.sh            # all: library, banmo, tests, benchmarks
#   bash tools/build.sh banmo      # only the executable
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_BUILD_DIR:-$root/build}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DBANMO_WERROR="${BANMO_WERROR:-ON}" >/dev/null
targets=()
for t in "$@"; do targets+=(--target "$t"); done
bash "$root/tools/cmake_build.sh" "$build" "${targets[@]}"
