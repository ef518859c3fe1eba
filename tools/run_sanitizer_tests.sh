#!/usr/bin/env bash
# Builds banmo-ceres with AddressSanitizer + UndefinedBehaviorSanitizer into
# build-asan/ (build type Sanitize: -O1 -g, assertions on; no benchmarks) and
# runs the quick test set under it. Any sanitizer report fails its test.
#   bash tools/run_sanitizer_tests.sh          # build + ctest -L quick
# BANMO_ASAN_BUILD_DIR overrides build-asan/, BANMO_JOBS the build's -j.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_ASAN_BUILD_DIR:-$root/build-asan}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Sanitize \
  -DBANMO_SANITIZE=address,undefined -DBANMO_WERROR=OFF -DBANMO_BUILD_BENCHMARKS=OFF >/dev/null
start=$(date +%s)
cmake --build "$build" -j "${BANMO_JOBS:-$(nproc)}"
echo "[time] sanitizer build $(($(date +%s) - start)) s"

# Stop at the first report with a stack trace; leaks are checked (LeakSanitizer)
# when each test process exits.
export ASAN_OPTIONS="halt_on_error=1:abort_on_error=0:detect_leaks=1:strict_string_checks=1:check_initialization_order=1:detect_stack_use_after_return=0:print_summary=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:print_summary=1"
cd "$build"
ctest --output-on-failure -j "$(nproc)" -L quick
