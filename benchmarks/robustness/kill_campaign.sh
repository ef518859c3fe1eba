#!/usr/bin/env bash
# kill -9 campaigns (issue 66, docs/robustness.md "Killed runs"): starts a
# command, kills it with SIGKILL after a random delay within its measured
# run time, then runs the next command a user would run and checks that it
# accepts what the killed run left.
#   bash benchmarks/robustness/kill_campaign.sh BANMO WORK [N] [COMMAND...]
# BANMO: the banmo binary (e.g. build/bin/banmo); WORK: a folder for the
# scenes and results (kept; the campaign resumes where it stopped: cycles
# already in WORK/results.tsv are not rerun); N: kills per command
# (default 20): cycles go on until N of them killed the command mid-run;
# COMMAND: any of solve, extract, prepare-add (default all).
#
# solve:       a 160-batch solve of a 2-video, 6-frame, 32 px synthetic scene
#              (problems/tiny.yaml with fewer batches, a checkpoint every 5
#              batches, one thread). Next command: `solve --resume` if the
#              killed run left OUT, else the same `solve` again. Then the
#              final OUT/checkpoint/params.bin and state.bin must be
#              byte-identical to an unkilled run's.
# extract:     `extract --resolution 128` of that solve's model, into a new
#              OUT (odd cycles) or into an OUT holding an earlier
#              `--resolution 64` extraction (even cycles). Right after the
#              kill, OUT must be absent or complete (every file of a
#              finished run, readable by `eval --pred OUT/frames`); the next
#              extract must succeed and leave no staging folder or
#              temporary file.
# prepare-add: `prepare --add` of a 12-frame, 96 px video to a 1-video
#              dataset. Next commands: `check` (must accept the dataset),
#              the same `prepare --add` (must succeed), `check` (2 videos).
# Every process runs under nice -n 10 (BANMO_NICE) with --threads 1.
# Results: one line per cycle in WORK/results.tsv (command, cycle, delay
# s, killed or finished first, outcome, detail); the summary is printed.
set -uo pipefail
banmo="$(realpath "${1:?usage: kill_campaign.sh BANMO WORK [N] [COMMAND...]}")"
work="${2:?usage: kill_campaign.sh BANMO WORK [N] [COMMAND...]}"
n="${3:-20}"
shift 3 2>/dev/null || shift $#
commands=("$@")
[ "${#commands[@]}" -gt 0 ] || commands=(solve extract prepare-add)
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
nice_level="${BANMO_NICE:-10}"
mkdir -p "$work"
work="$(realpath "$work")"
results="$work/results.tsv"
touch "$results"
run() { nice -n "$nice_level" "$banmo" "$@"; }

# --- scenes (made once) ------------------------------------------------------
setup() {
  cd "$work" || exit 1
  if [ ! -f ds/manifest.yaml ]; then
    run synth --videos 2 --frames 6 --size 32 --gaps 1,2 --threads 1 --out ds >/dev/null || exit 1
  fi
  if [ ! -f cfg.yaml ]; then
    sed -e 's/batches: 200/batches: 60/' -e 's/threads: 0/threads: 1/' \
      -e 's/^  log_every: 50$/  log_every: 50\n  checkpoint_every: 5/' \
      "$root/problems/tiny.yaml" >cfg.yaml.tmp && mv cfg.yaml.tmp cfg.yaml
  fi
  if [ ! -f ref/checkpoint/params.bin ]; then
    rm -rf ref
    local t0 t1
    t0=$(date +%s.%N)
    run solve --data ds --config cfg.yaml --out ref --threads 1 --no-extract --no-eval \
      --quiet >/dev/null 2>&1 || { echo "reference solve failed" >&2; exit 1; }
    t1=$(date +%s.%N)
    echo "$t0 $t1" | awk '{print $2 - $1}' >ref_solve_seconds
  fi
  if [ ! -f ex_old/extract.json ]; then
    rm -rf ex_old
    run extract --model ref/checkpoint --out ex_old --resolution 64 --threads 1 >/dev/null ||
      exit 1
  fi
  if [ ! -f ex_ref/extract.json ]; then
    rm -rf ex_ref
    local t0 t1
    t0=$(date +%s.%N)
    run extract --model ref/checkpoint --out ex_ref --resolution 128 --threads 1 >/dev/null ||
      exit 1
    t1=$(date +%s.%N)
    echo "$t0 $t1" | awk '{print $2 - $1}' >ref_extract_seconds
  fi
  if [ ! -f src/manifest.yaml ]; then
    run synth --videos 2 --frames 12 --size 96 --gaps 1,2 --threads 1 --out src >/dev/null ||
      exit 1
  fi
  if [ ! -f base/manifest.yaml ]; then
    rm -rf base
    run prepare --frames src/video_000/rgb --masks src/video_000/mask --out base --gaps 1,2 \
      >/dev/null 2>&1 || exit 1
  fi
  if [ ! -f ref_add_seconds ]; then
    rm -rf add_ref
    cp -a base add_ref
    local t0 t1
    t0=$(date +%s.%N)
    run prepare --frames src/video_001/rgb --masks src/video_001/mask --out add_ref --add \
      --gaps 1,2 >/dev/null 2>&1 || exit 1
    t1=$(date +%s.%N)
    echo "$t0 $t1" | awk '{print $2 - $1}' >ref_add_seconds
  fi
}

# A random delay in [0.02, 1.1 x the reference run time] seconds.
random_delay() {
  awk -v t="$(cat "$1")" -v r="$RANDOM" 'BEGIN { printf "%.3f", 0.02 + (r / 32767) * 1.1 * t }'
}

# Runs "$@" in the background, kills it with SIGKILL after $delay s; sets
# $fate to killed or finished (exit status of a run that ended first).
kill_after() {
  # nice execs banmo: $! is banmo's pid (a shell function here would put a
  # subshell between them, and the kill would miss banmo).
  nice -n "$nice_level" "$banmo" "$@" >"$work/killed.log" 2>&1 &
  local pid=$!
  sleep "$delay"
  kill -9 "$pid" 2>/dev/null
  { wait "$pid"; } 2>/dev/null
  local status=$?
  if [ "$status" -eq 137 ]; then fate=killed; else fate="finished($status)"; fi
}

record() {  # command cycle outcome detail
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$1" "$2" "$delay" "$fate" "$3" "$4" >>"$results"
  printf '%-12s %3s  delay %6s s  %-12s %-4s %s\n' "$1" "$2" "$delay" "$fate" "$3" "$4"
}

# Entries of a folder and of its parent that belong to a killed run.
leftovers() {
  local out="$1"
  {
    find "$out" -name '*.tmp.*' -o -name '.*staging*' 2>/dev/null
    find "$(dirname "$out")" -maxdepth 1 -name ".$(basename "$out").*staging*" 2>/dev/null
  } | sort | tr '\n' ' '
}

# Same contents (extract.json: but its timings).
same() {
  case "$1" in
    *extract.json) cmp -s <(grep -v seconds "$1") <(grep -v seconds "$2") ;;
    *) cmp -s "$1" "$2" ;;
  esac
}

# The error line of the last command's log (else its last line).
why() { grep -m1 'error' "$work/next.log" || tail -1 "$work/next.log"; }

# Relative file list of an extraction (no hidden entries).
files_of() { (cd "$1" && find . -not -path '*/.*' -type f | sort); }

cycle_solve() {
  local i="$1" out="$work/solve_k"
  rm -rf "$out"
  delay="$(random_delay "$work/ref_solve_seconds")"
  kill_after solve --data ds --config cfg.yaml --out "$out" --threads 1 --no-extract --no-eval \
    --quiet
  local left="none" next status
  if [ -e "$out" ]; then
    left="$(ls -A "$out" | tr '\n' ' ')"
    local at
    at="$(awk '/^stage:/ { s = $2 } /^batch:/ { b = $2 } END { if (s != "") print s "/" b }' \
      "$out/checkpoint/checkpoint.yaml" 2>/dev/null)"
    left="${left% }${at:+; checkpoint at stage/batch $at}"
    next="solve --resume"
    run solve --data ds --config cfg.yaml --out "$out" --threads 1 --no-extract --no-eval \
      --quiet --resume >"$work/next.log" 2>&1
  else
    next="solve"
    run solve --data ds --config cfg.yaml --out "$out" --threads 1 --no-extract --no-eval \
      --quiet >"$work/next.log" 2>&1
  fi
  status=$?
  if [ "$status" -ne 0 ]; then
    record solve "$i" FAIL "$next exit $status: $(why) (left: $left)"
  elif cmp -s "$out/checkpoint/params.bin" ref/checkpoint/params.bin &&
    cmp -s "$out/checkpoint/state.bin" ref/checkpoint/state.bin; then
    record solve "$i" ok "$next; params.bin, state.bin identical (left: $left)"
  else
    record solve "$i" FAIL "$next; params.bin or state.bin differ (left: $left)"
  fi
}

cycle_extract() {
  local i="$1" out="$work/extract_k" mode
  rm -rf "$out" "$work"/.extract_k.*
  if [ $((i % 2)) -eq 1 ]; then mode=new; else mode=existing; cp -a ex_old "$out"; fi
  delay="$(random_delay "$work/ref_extract_seconds")"
  kill_after extract --model ref/checkpoint --out "$out" --resolution 128 --threads 1
  local state detail="" fail=0
  if [ ! -e "$out" ]; then
    state="absent"
  elif [ "$(files_of "$out")" != "$(files_of ex_ref)" ]; then
    state="INCOMPLETE"
    fail=1
  else
    # Complete: every file either the earlier run's or the killed run's
    # (some, e.g. bones.ply, are the same in both).
    local old=0 new=0 both=0 f
    while read -r f; do
      if same "$out/$f" "ex_ref/$f" && [ -e "ex_old/$f" ] && same "$out/$f" "ex_old/$f"; then
        both=$((both + 1))
      elif same "$out/$f" "ex_ref/$f"; then
        new=$((new + 1))
      elif same "$out/$f" "ex_old/$f"; then
        old=$((old + 1))
      else
        fail=1
        detail+=" $f is neither;"
      fi
    done < <(files_of "$out")
    state="complete (files of the earlier run $old, of the killed run $new, same in both $both)"
    if ! run eval --pred "$out/frames" --gt ds --threads 1 --gt-mode vertices \
      --icp-iterations 0 >"$work/next.log" 2>&1; then
      fail=1
      detail+=" eval refused: $(why);"
    fi
  fi
  local left
  left="$(leftovers "$out")"
  if ! run extract --model ref/checkpoint --out "$out" --resolution 128 --threads 1 \
    >"$work/next.log" 2>&1; then
    fail=1
    detail+=" next extract failed: $(why);"
  else
    local f
    while read -r f; do
      same "$out/$f" "ex_ref/$f" || {
        fail=1
        detail+=" after the rerun $f differs;"
      }
    done < <(files_of ex_ref)
    [ "$(files_of "$out")" = "$(files_of ex_ref)" ] || {
      fail=1
      detail+=" after the rerun the file list differs;"
    }
    local after
    after="$(leftovers "$out")"
    [ -z "$after" ] || {
      fail=1
      detail+=" left after the rerun: $after;"
    }
  fi
  left="${left//$work\//}"
  record extract "$i" "$([ $fail -eq 0 ] && echo ok || echo FAIL)" \
    "$mode OUT; after the kill: $state${left:+, staging/temporary: $left}; rerun ok${detail}"
}

cycle_add() {
  local i="$1" d="$work/add_k"
  rm -rf "$d" "$work"/add_k.add-*
  cp -a base "$d"
  delay="$(random_delay "$work/ref_add_seconds")"
  kill_after prepare --frames src/video_001/rgb --masks src/video_001/mask --out "$d" --add \
    --gaps 1,2
  local fail=0 detail="" left
  left="$(cd "$work" && ls -d add_k.add-* 2>/dev/null | tr '\n' ' ')"
  local videos
  videos="$(grep -c '^  - name:' "$d/manifest.yaml" 2>/dev/null || echo '?')"
  if ! run check "$d" >"$work/next.log" 2>&1; then
    fail=1
    detail+=" check refused: $(why);"
  fi
  if [ "$fate" = killed ] || [ "$videos" = 1 ]; then
    if [ "$(grep -c '^  - name:' "$d/manifest.yaml")" = 1 ]; then
      if ! run prepare --frames src/video_001/rgb --masks src/video_001/mask --out "$d" --add \
        --gaps 1,2 >"$work/next.log" 2>&1; then
        fail=1
        detail+=" retried add failed: $(why);"
      fi
    fi
  fi
  if ! run check "$d" >"$work/next.log" 2>&1; then
    fail=1
    detail+=" final check refused: $(why);"
  fi
  local final
  final="$(grep -c '^  - name:' "$d/manifest.yaml")"
  [ "$final" = 2 ] || {
    fail=1
    detail+=" $final videos at the end;"
  }
  [ -z "$(cd "$work" && ls -d add_k.add-* 2>/dev/null)" ] || {
    fail=1
    detail+=" staging folder left;"
  }
  record prepare-add "$i" "$([ $fail -eq 0 ] && echo ok || echo FAIL)" \
    "videos in the manifest after the kill: $videos${left:+, staging: $left}; check ok${detail}"
}

setup
cd "$work" || exit 1
for c in "${commands[@]}"; do
  # Cycles go on until N of them killed the command mid-run (a run that
  # ended before its delay counts as a cycle, not as a kill).
  while :; do
    killed="$(awk -F'\t' -v c="$c" '$1 == c && $4 == "killed"' "$results" | wc -l)"
    [ "$killed" -lt "$n" ] || break
    i=$(($(awk -F'\t' -v c="$c" '$1 == c' "$results" | wc -l) + 1))
    case "$c" in
      solve) cycle_solve "$i" ;;
      extract) cycle_extract "$i" ;;
      prepare-add) cycle_add "$i" ;;
      *)
        echo "unknown command $c (solve, extract, prepare-add)" >&2
        exit 2
        ;;
    esac
  done
done
echo "reference run times (s): solve $(cat ref_solve_seconds), extract $(cat ref_extract_seconds)," \
  "prepare --add $(cat ref_add_seconds)"
awk -F'\t' '{ n[$1]++; if ($4 == "killed") k[$1]++; if ($5 == "ok") ok[$1]++ }
  END { for (c in n) printf "%-12s %d cycles, %d killed mid-run, %d ok, %d failed\n",
        c, n[c], k[c], ok[c], n[c] - ok[c] }' "$results"
! grep -q $'\tFAIL\t' "$results"
