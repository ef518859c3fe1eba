#!/usr/bin/env bash
# Builds banmo-ceres with AddressSanitizer + UndefinedBehaviorSanitizer into
# build-asan/ (build type Sanitize: -O1 -g, assertions on; no benchmarks) and
# runs the quick test set of every folder of tests/ under it, the
# command-line tests included. Any sanitizer report (a leak at exit included:
# LeakSanitizer) fails its test. In this build the losses' numeric-
# differentiation checks run on one term and ray
# (tests/losses/ray_jacobian_test.cc, NumericSubset; BANMO_FULL_NUMERIC=1 runs
# them all). The benchmarks' own tests (benchmarks/solver) run in the Release
# part only.
#   bash tools/run_sanitizer_tests.sh          # build + ctest -L quick + fuzz smoke
# Then the fuzz smoke (docs/robustness.md, "Fuzzing"): the fuzz targets of
# fuzz/ built in the same tree with fuzz/smoke_main.cc (replay of the seed
# corpus from tools/make_fuzz_corpus.sh, then random mutations; not
# coverage-guided), each for BANMO_FUZZ_SMOKE_SECONDS (default 10; 0 skips
# the smoke). A finding fails the script.
# BANMO_SANITIZE_TEST_DIRS="losses;optim" limits it to those folders of tests/
# (local iteration); BANMO_ASAN_BUILD_DIR overrides build-asan/, BANMO_JOBS
# the build's -j.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_ASAN_BUILD_DIR:-$root/build-asan}"
all_dirs=""
for d in "$root"/tests/*/; do
  d="$(basename "$d")"
  if grep -q '^banmo_add_test(' "$root/tests/$d/CMakeLists.txt" 2>/dev/null; then
    all_dirs+="${all_dirs:+;}$d"
  fi
done
dirs="${BANMO_SANITIZE_TEST_DIRS:-$all_dirs}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Sanitize \
  -DBANMO_SANITIZE=address,undefined -DBANMO_WERROR=OFF -DBANMO_BUILD_BENCHMARKS=OFF \
  -DBANMO_ONLY_TEST_DIRS="$dirs" -DBANMO_FUZZ_SMOKE=ON >/dev/null
smoke_seconds="${BANMO_FUZZ_SMOKE_SECONDS:-10}"
# Only the test programs of those folders (and the libraries they link).
targets=()
for d in ${dirs//;/ }; do
  for t in $(sed -n 's/^banmo_add_test(\([a-z_0-9]*\).*/\1/p' "$root/tests/$d/CMakeLists.txt"); do
    targets+=(--target "$t")
  done
done
start=$(date +%s)
bash "$root/tools/cmake_build.sh" "$build" "${targets[@]}"
echo "[time] sanitizer build $(($(date +%s) - start)) s"
if [ "$smoke_seconds" != 0 ]; then
  start=$(date +%s)
  bash "$root/tools/cmake_build.sh" "$build" --target fuzz_all --target banmo
  echo "[time] fuzz smoke targets build $(($(date +%s) - start)) s"
fi

# Stop at the first report with a stack trace; leaks are checked (LeakSanitizer)
# when each test process exits.
export ASAN_OPTIONS="halt_on_error=1:abort_on_error=0:detect_leaks=1:strict_string_checks=1:check_initialization_order=1:detect_stack_use_after_return=0:print_summary=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:print_summary=1"
cd "$build"
ctest --output-on-failure -j "$(nproc)" -L quick
[ "$smoke_seconds" != 0 ] || exit 0

# Fuzz smoke: every target for $smoke_seconds s over its seed corpus.
start=$(date +%s)
rm -rf "$build/fuzz_corpus" "$build/fuzz_smoke"
ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0" bash "$root/tools/make_fuzz_corpus.sh" \
  "$build/bin/banmo" "$build/fuzz_corpus" >/dev/null
mkdir -p "$build/fuzz_smoke"
echo "[time] fuzz corpus $(($(date +%s) - start)) s"
found=0
for exe in "$build"/fuzz/fuzz_*_smoke; do
  t="$(basename "$exe" _smoke)"
  log="$build/fuzz_smoke/$t.log"
  # Leaks are not findings here (the libFuzzer runs do not check them either).
  if (cd "$build/fuzz_smoke" && ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0" \
    "$exe" -max_total_time="$smoke_seconds" "$build/fuzz_corpus/$t" >"$log" 2>&1); then
    echo "[fuzz] $(tail -1 "$log")"
  else
    echo "[fuzz] $t: FINDING (input in $build/fuzz_smoke/smoke-crash-*)"
    tail -30 "$log"
    found=1
  fi
done
echo "[time] fuzz smoke $(($(date +%s) - start)) s"
exit "$found"
