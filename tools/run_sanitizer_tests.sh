#!/usr/bin/env bash
# Builds banmo-ceres with AddressSanitizer + UndefinedBehaviorSanitizer into
# build-asan/ (build type Sanitize: -O1 -g, assertions on; no benchmarks) and
# runs the unit tests of util, geometry, field, deform, volume, model, losses
# and optim under it (BANMO_SANITIZE_TEST_DIRS), the solver's command-line
# test included. Any sanitizer report fails its test. In this build the
# losses' numeric-differentiation checks run on one term and ray
# (tests/losses/ray_jacobian_test.cc, NumericSubset; BANMO_FULL_NUMERIC=1 runs
# them all). Not yet under the sanitizers: extract, eval, synth, gltf,
# visualize, io and their command-line tests (benchmarks/README.md, "CI").
#   bash tools/run_sanitizer_tests.sh          # build + ctest -L quick
# BANMO_ASAN_BUILD_DIR overrides build-asan/, BANMO_JOBS the build's -j.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_ASAN_BUILD_DIR:-$root/build-asan}"
dirs="${BANMO_SANITIZE_TEST_DIRS:-util;geometry;field;deform;volume;model;losses;optim}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Sanitize \
  -DBANMO_SANITIZE=address,undefined -DBANMO_WERROR=OFF -DBANMO_BUILD_BENCHMARKS=OFF \
  -DBANMO_ONLY_TEST_DIRS="$dirs" >/dev/null
# Only the test programs of those folders (and the libraries they link).
targets=()
for d in ${dirs//;/ }; do
  for t in $(sed -n 's/^banmo_add_test(\([a-z_0-9]*\).*/\1/p' "$root/tests/$d/CMakeLists.txt"); do
    targets+=(--target "$t")
  done
done
start=$(date +%s)
cmake --build "$build" -j "${BANMO_JOBS:-$(nproc)}" "${targets[@]}"
echo "[time] sanitizer build $(($(date +%s) - start)) s"

# Stop at the first report with a stack trace; leaks are checked (LeakSanitizer)
# when each test process exits.
export ASAN_OPTIONS="halt_on_error=1:abort_on_error=0:detect_leaks=1:strict_string_checks=1:check_initialization_order=1:detect_stack_use_after_return=0:print_summary=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:print_summary=1"
cd "$build"
ctest --output-on-failure -j "$(nproc)" -L quick
