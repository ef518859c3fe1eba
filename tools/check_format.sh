#!/usr/bin/env bash
# Lists the project's C++ files (src, include, tools, tests, benchmarks) that
# clang-format (Debian's, with the repository's .clang-format) would change,
# and exits 1 if there are any. Fix them with: clang-format -i <files>.
# BANMO_CLANG_FORMAT overrides the program (default: clang-format).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
clang_format="${BANMO_CLANG_FORMAT:-clang-format}"
if ! command -v "$clang_format" >/dev/null; then
  echo "[format] $clang_format not found (bash tools/install_deps.sh installs it)" >&2
  exit 2
fi
# Tracked and untracked-but-not-ignored files, so a new file is checked before it is added.
mapfile -t files < <(git ls-files --cached --others --exclude-standard -- \
  src include tools tests benchmarks fuzz | grep -E '\.(cc|cpp|h|hpp)$' | sort -u |
  while read -r f; do [ -f "$f" ] && echo "$f"; done)  # skip files deleted but still indexed
[ ${#files[@]} -gt 0 ] || { echo "[format] no files"; exit 0; }
# One clang-format process for all files: --dry-run reports each change as
# "<file>:<line>:<col>: warning: code should be clang-formatted".
report="$("$clang_format" --style=file --dry-run "${files[@]}" 2>&1)" || {
  echo "$report" >&2
  exit 2
}
mapfile -t bad < <(sed -n 's/^\(.*\):[0-9]*:[0-9]*: warning: code should be clang-formatted.*/\1/p' \
  <<<"$report" | sort -u)
if [ ${#bad[@]} -gt 0 ]; then
  echo "[format] ${#bad[@]} of ${#files[@]} files are not clang-formatted ($("$clang_format" --version)):"
  printf '  %s\n' "${bad[@]}"
  echo "[format] fix with: clang-format -i ${bad[*]}"
  exit 1
fi
echo "[format] all ${#files[@]} files clang-formatted"
