#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang under ASan + UBSan in
# build-fuzz/ (BANMO_FUZZ_BUILD_DIR), makes their seed corpora and runs each
# for SECONDS, then prints the executions per target.
#   bash tools/run_fuzz.sh 60
# Needs Debian's clang and libclang-rt-14-dev. Findings (crash inputs) are
# kept in build-fuzz/fuzz_findings/<target>/; the exit status is 1 if any.
set -euo pipefail
seconds="${1:?usage: run_fuzz.sh SECONDS}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_FUZZ_BUILD_DIR:-$root/build-fuzz}"
CXX=clang++ cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Sanitize \
  -DBANMO_SANITIZE=address,undefined,fuzzer-no-link -DBANMO_FUZZ=ON \
  -DBANMO_BUILD_TESTS=OFF -DBANMO_BUILD_BENCHMARKS=OFF -DBANMO_WERROR=OFF >/dev/null
cmake --build "$build" -j "${BANMO_JOBS:-$(nproc)}" --target fuzz_all banmo
rm -rf "$build/fuzz_corpus"
cmake --build "$build" --target fuzz_corpus
found=0
printf '%-15s %12s %10s %s\n' target executions exec/s result
for exe in "$build"/fuzz/fuzz_*; do
  [ -x "$exe" ] || continue
  t="$(basename "$exe")"
  corpus="$build/fuzz_work/$t"
  findings="$build/fuzz_findings/$t"
  mkdir -p "$corpus" "$findings"
  cp -n "$build/fuzz_corpus/$t/"* "$corpus/" 2>/dev/null || true
  log="$build/fuzz_work/$t.log"
  status=0
  (cd "$findings" && ASAN_OPTIONS=detect_leaks=0 "$exe" -max_total_time="$seconds" \
    -print_final_stats=1 -rss_limit_mb=4096 -max_len=1048576 "$corpus" >"$log" 2>&1) || status=$?
  execs="$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')"
  rate="$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')"
  result="ok"
  if [ "$status" -ne 0 ]; then result="FINDING (see $log)"; found=1; fi
  printf '%-15s %12s %10s %s\n' "$t" "$execs" "$rate" "$result"
done
exit "$found"
