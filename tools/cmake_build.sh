#!/usr/bin/env bash
# cmake --build for the CI scripts (tools/build.sh, tools/run_sanitizer_tests.sh):
#   bash tools/cmake_build.sh BUILD_DIR [cmake --build options and --target ...]
# Builds at -j BANMO_JOBS (default: nproc). If the build fails, prints what
# the machine had left (disk, memory, ccache) and builds once more at -j 1
# without ccache, so that a step that failed without a message (a compiler
# killed for memory, or ccache unable to write its copy of the compiler's
# output on a full disk) either passes or fails again with the compiler's own
# error. A real compile error fails both times.
set -euo pipefail
build="$1"
shift
if cmake --build "$build" -j "${BANMO_JOBS:-$(nproc)}" "$@"; then
  exit 0
fi
echo "[build] failed in $build; the machine now:" >&2
df -h "$build" /tmp >&2 || true
free -m >&2 || true
command -v ccache >/dev/null && ccache -s >&2 || true
echo "[build] once more at -j 1 without ccache" >&2
CCACHE_DISABLE=1 cmake --build "$build" -j 1 "$@"
