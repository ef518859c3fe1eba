#!/usr/bin/env bash
# README command 2: install what is missing, build, run the test suite.
# BANMO_TEST_LABELS selects a ctest label set (default: all tests).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/tools/install_deps.sh"
bash "$root/tools/build.sh"
build="${BANMO_BUILD_DIR:-$root/build}"
label_args=()
[ -z "${BANMO_TEST_LABELS:-}" ] || label_args=(-L "$BANMO_TEST_LABELS")
cd "$build"
ctest --output-on-failure -j "$(nproc)" "${label_args[@]}"
