#!/usr/bin/env bash
# README command 2, and CI (.ci/run): install what is missing, then
#   1. format:    tools/check_format.sh (clang-format, fails on unformatted code)
#   2. sanitizer: tools/run_sanitizer_tests.sh (ASan + UBSan build in build-asan/,
#                 assertions on, quick test set, then each fuzz target of fuzz/
#                 for 10 s with the smoke driver: docs/robustness.md)
#   3. release:   tools/build.sh (Release, -Werror on our code, build/) + ctest
# and print the wall time of each part. The Release ctest runs last, so the last
# lines are its summary. Stops at the first part that fails.
# BANMO_TEST_LABELS selects the Release ctest label set (default: all tests).
# BANMO_SANITIZE=0 skips part 2 for local iteration (not under CI=true).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/tools/install_deps.sh"

times=()
part_start=0
begin() {
  part_start=$(date +%s)
  echo "[ci] $1"
}
end() {
  times+=("$1 $(($(date +%s) - part_start)) s")
  echo "[time] ${times[-1]}"
}

begin "format check"
bash "$root/tools/check_format.sh"
end format

if [ "${BANMO_SANITIZE:-1}" = 0 ] && [ "${CI:-}" != true ]; then
  echo "[ci] sanitizer part skipped (BANMO_SANITIZE=0)"
else
  begin "ASan + UBSan build, quick tests and fuzz smoke (build-asan/)"
  bash "$root/tools/run_sanitizer_tests.sh"
  end "sanitizer build + quick ctest + fuzz smoke"
fi

begin "Release build (build/)"
bash "$root/tools/build.sh"
end "release build"

build="${BANMO_BUILD_DIR:-$root/build}"
label_args=()
[ -z "${BANMO_TEST_LABELS:-}" ] || label_args=(-L "$BANMO_TEST_LABELS")
echo "[time] so far: ${times[*]/%/;} then the Release ctest (its total below)"
cd "$build"
ctest --output-on-failure -j "$(nproc)" "${label_args[@]}"
