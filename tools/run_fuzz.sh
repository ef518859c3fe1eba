#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang under ASan + UBSan in
# build-fuzz/ (BANMO_FUZZ_BUILD_DIR), makes their seed corpora and runs each
# for SECONDS, then prints the executions per target.
#   bash tools/run_fuzz.sh 60                       # every target, 60 s each
#   bash tools/run_fuzz.sh 600 fuzz_npy fuzz_png    # these targets only
# The targets run one after another; a long campaign can be run piece by
# piece (each call appends one line per target to
# build-fuzz/fuzz_results.tsv: date, target, seconds, executions, exec/s,
# result). The corpus of each target (build-fuzz/fuzz_work/<target>/) is
# kept between calls, so a later run continues where an earlier one left.
# BANMO_FUZZ_NO_BUILD=1 skips the configure/build/seed step (the targets and
# build-fuzz/fuzz_corpus must exist), e.g. to run two targets at once from
# two shells. BANMO_FUZZ_NICE=19 runs the fuzzers under nice.
# Needs Debian's clang and libclang-rt-14-dev. Findings (crash inputs) are
# kept in build-fuzz/fuzz_findings/<target>/; the exit status is 1 if any.
set -euo pipefail
seconds="${1:?usage: run_fuzz.sh SECONDS [TARGET...]}"
shift
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${BANMO_FUZZ_BUILD_DIR:-$root/build-fuzz}"
if [ "${BANMO_FUZZ_NO_BUILD:-0}" != 1 ]; then
  CXX=clang++ cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Sanitize \
    -DBANMO_SANITIZE=address,undefined,fuzzer-no-link -DBANMO_FUZZ=ON \
    -DBANMO_BUILD_TESTS=OFF -DBANMO_BUILD_BENCHMARKS=OFF -DBANMO_WERROR=OFF >/dev/null
  cmake --build "$build" -j "${BANMO_JOBS:-$(nproc)}" --target fuzz_all banmo
  rm -rf "$build/fuzz_corpus"
  cmake --build "$build" --target fuzz_corpus
fi
exes=()
if [ "$#" -eq 0 ]; then
  for exe in "$build"/fuzz/fuzz_*; do [ -x "$exe" ] && exes+=("$exe"); done
else
  for t in "$@"; do
    [ -x "$build/fuzz/$t" ] || { echo "run_fuzz.sh: no fuzz target $build/fuzz/$t" >&2; exit 2; }
    exes+=("$build/fuzz/$t")
  done
fi
found=0
printf '%-15s %8s %12s %10s %s\n' target seconds executions exec/s result
for exe in "${exes[@]}"; do
  t="$(basename "$exe")"
  corpus="$build/fuzz_work/$t"
  findings="$build/fuzz_findings/$t"
  mkdir -p "$corpus" "$findings"
  cp -n "$build/fuzz_corpus/$t/"* "$corpus/" 2>/dev/null || true
  log="$build/fuzz_work/$t.log"
  status=0
  start=$(date +%s)
  (cd "$findings" && ASAN_OPTIONS=detect_leaks=0 nice -n "${BANMO_FUZZ_NICE:-0}" "$exe" \
    -max_total_time="$seconds" -print_final_stats=1 -rss_limit_mb=4096 -max_len=1048576 \
    "$corpus" >"$log" 2>&1) || status=$?
  wall=$(($(date +%s) - start))
  execs="$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')"
  rate="$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')"
  result="ok"
  if [ "$status" -ne 0 ]; then result="FINDING (see $log)"; found=1; fi
  printf '%-15s %8s %12s %10s %s\n' "$t" "$wall" "$execs" "$rate" "$result"
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$(date -u +%FT%TZ)" "$t" "$wall" "$execs" "$rate" \
    "$result" >>"$build/fuzz_results.tsv"
done
exit "$found"
