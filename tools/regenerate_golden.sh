#!/usr/bin/env bash
# Regenerates the golden residual values of tests/losses/golden_test.cc (the
# residual rows of the fixed-seed tiny scene, tests/common/test_scene.h) from
# the current code: builds losses_test (Release, build/), runs the golden test
# with BANMO_PRINT_GOLDEN=1, replaces the kGolden block in the file and
# clang-formats it. Only for an intended change of a formula, a layout or an
# initialisation: review `git diff tests/losses/golden_test.cc`, update the
# "Regenerated <date>: <why>" comment above kGolden, and say so in the commit.
#   bash tools/regenerate_golden.sh
# BANMO_BUILD_DIR and BANMO_JOBS as for tools/build.sh.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_BUILD_DIR:-$root/build}"
test_file="$root/tests/losses/golden_test.cc"
bash "$root/tools/build.sh" losses_test
# The test fails when the values changed; its printout is what counts.
output="$(BANMO_PRINT_GOLDEN=1 "$build/tests/losses/losses_test" \
  --gtest_filter='RayResiduals.GoldenValuesOnTinyScene' || true)"
printed="$(sed -n '/^const std::vector<std::vector<double>> kGolden = {$/,/};$/p' <<<"$output")"
if [[ -z "$printed" ]]; then
  echo "regenerate_golden: losses_test printed no kGolden block" >&2
  exit 1
fi
blocks="$(grep -c '^const std::vector<std::vector<double>> kGolden = {$' "$test_file" || true)"
if [[ "$blocks" != 1 ]]; then
  echo "regenerate_golden: expected one kGolden block in $test_file, found $blocks" >&2
  exit 1
fi
tmp="$(mktemp)"
# Replace the lines from the kGolden line through its closing "};".
GOLDEN="$printed" awk '
  /^const std::vector<std::vector<double>> kGolden = \{$/ { print ENVIRON["GOLDEN"]; skip = 1; next }
  skip && /\};$/ { skip = 0; next }
  !skip { print }
' "$test_file" >"$tmp"
cat "$tmp" >"$test_file"  # keeps the file's mode
rm -f "$tmp"
"${BANMO_CLANG_FORMAT:-clang-format}" -i --style=file "$test_file"
echo "regenerate_golden: rewrote kGolden in $test_file; review with git diff"
