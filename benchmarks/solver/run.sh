#!/usr/bin/env bash
# Speed against error and stability, one command:
#   bash benchmarks/solver/run.sh [--quick] [--fox] [--resume] [--only NAME,NAME] [--no-stability]
#                                 [--no-compare] [--jobs N]
# Builds banmo and banmo_trace, makes the named scenes (scenes.txt, cached),
# runs every named configuration (configs.txt) on the comparison scene and
# every stability case (stability.txt) with banmo_trace under the mode's
# budget (budgets.txt), then draws the plots (plots/<mode>_<axis>.png), writes
# results/<mode>/traces.csv and the Pareto and stability tables into
# benchmarks/README.md (between marker comments), and prints its own run time.
# README.md in this folder documents everything.
#   --quick         tiny scenes and budgets: proves the pipeline in minutes
#   --fox           (full mode) also adam / lm / alternate on the Fox for 30 min each
#   --resume        keep runs that finished (OUT/done, or listed in results/<mode>/done.csv)
#                   instead of re-running them
#   --only a,b      run only these configuration / stability names (tables use all CSVs present)
#   --jobs N        N runs at a time, each with nproc / N threads (default 1: one run on
#                   every core)
# Environment: BANMO_BUILD_DIR (default build/), BANMO_SOURCE_DIR (sources to
# build, default this checkout), BANMO_BENCH_OUT (default runs/bench),
# BANMO_BENCH_RESULTS (plots/ and results/, default this folder),
# BANMO_BENCH_README (default benchmarks/README.md), BANMO_BENCH_BUDGET (full
# mode: the time cap of a run in solve seconds, default budgets.txt's 900).
set -euo pipefail
here="$(cd -P "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd -P "$here/../.." && pwd)"
src="${BANMO_SOURCE_DIR:-$root}"
build="${BANMO_BUILD_DIR:-$root/build}"
out_root="${BANMO_BENCH_OUT:-$root/runs/bench}"

args_given="$*"
mode=full
fox=0
resume=0
only=""
do_stability=1
do_compare=1
jobs=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) mode=quick ;;
    --fox) fox=1 ;;
    --resume) resume=1 ;;
    --only) only="$2"; shift ;;
    --no-stability) do_stability=0 ;;
    --no-compare) do_compare=0 ;;
    --jobs) jobs="$2"; shift ;;
    -h|--help) sed -n 2,23p "${BASH_SOURCE[0]}"; exit 0 ;;
    *) echo "run.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done
if ! [[ $jobs =~ ^[1-9][0-9]*$ ]]; then
  echo "run.sh: --jobs expects a positive integer, got '$jobs'" >&2; exit 2
fi
if [[ $fox == 1 && $mode == quick ]]; then
  echo "run.sh: --fox is a full-mode option" >&2; exit 2
fi

start=$(date +%s)
echo "[build] banmo banmo_trace in $build (sources $src)"
cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j "${BANMO_JOBS:-$(nproc)}" --target banmo banmo_trace
banmo="$build/bin/banmo"
trace="$build/bin/banmo_trace"

# Mode settings: base config, its budget (budgets.txt) and the trace schedule.
budget_line=$(awk -v m="$mode" '$1 == m {$1 = ""; print}' "$here/budgets.txt")
if [[ -z "$budget_line" ]]; then echo "run.sh: no '$mode' line in budgets.txt" >&2; exit 2; fi
read -r -a budget <<<"$budget_line"
if [[ $mode == quick ]]; then
  base="$root/problems/tiny.yaml"
  schedule=(--every-batches 15 --resolution 40 --frame-step 10)
  compare_scene=quad_q
else
  base="$root/problems/default.yaml"
  if [[ -n "${BANMO_BENCH_BUDGET:-}" ]]; then
    for i in "${!budget[@]}"; do
      [[ ${budget[$i]} == --max-solve-seconds ]] && budget[$((i + 1))]="$BANMO_BENCH_BUDGET"
    done
  fi
  schedule=(--every-seconds 120 --resolution 64 --frame-step 8 --final-resolution 128)
  compare_scene=quad
fi
threads=$(( $(nproc) / jobs ))
(( threads < 1 )) && threads=1
work="$out_root/$mode"
scenes_dir="$out_root/scenes"
mkdir -p "$work" "$scenes_dir"

if [[ $resume == 1 ]]; then
  # Runs that finished in an earlier run.sh (possibly on another machine or
  # in another session) come back from the committed results/<mode>/ CSVs.
  python3 "$here/summarize.py" --restore --mode "$mode" --work "$work" \
    --results "${BANMO_BENCH_RESULTS:-$here}"
fi

selected() {  # selected NAME: is NAME in --only (or --only empty)?
  [[ -z "$only" ]] && return 0
  [[ ",$only," == *",$1,"* ]]
}
mode_ok() {  # mode_ok MODES
  [[ $1 == all || $1 == "$mode" || ( $1 == fox && $fox == 1 ) ]]
}

make_scene() {  # make_scene NAME
  local name="$1" line
  line=$(awk -v n="$name" '$1 !~ /^#/ && $2 == n' "$here/scenes.txt")
  if [[ -z "$line" ]]; then echo "run.sh: scene '$name' is not in scenes.txt" >&2; exit 2; fi
  read -r _ _ rig videos frames size noise gaps seed scale anim <<<"$line"
  local dir="$scenes_dir/$name"
  if [[ -f "$dir/manifest.yaml" ]]; then return; fi
  [[ $rig == *.glb || $rig == *.gltf ]] && rig="$root/$rig"
  local extra=()
  [[ -n "${anim:-}" ]] && extra=(--animation "$anim")
  # pose_noise_deg: DEG (exact model) or MODEL:DEG, e.g. gaussian:50.
  local model=exact
  if [[ $noise == *:* ]]; then model="${noise%%:*}"; noise="${noise#*:}"; fi
  echo "[scene] $name: $rig, $videos x $frames frames, ${size} px, noise $noise deg ($model), gaps $gaps, scale $scale"
  "$banmo" synth --rig "$rig" "${extra[@]}" --videos "$videos" --frames "$frames" --size "$size" \
    --pose-noise "$noise" --pose-noise-model "$model" --gaps "$gaps" --seed "$seed" \
    --object-scale "$scale" --out "$dir" --overwrite >"$scenes_dir/$name.log"
}

run_trace() {  # run_trace KIND NAME SCENE BASE [extra args...] -- OVERRIDES...
  local kind="$1" name="$2" scene="$3" cfg="$4"
  shift 4
  local extra=()
  while [[ $# -gt 0 && "$1" != "--" ]]; do extra+=("$1"); shift; done
  [[ $# -gt 0 ]] && shift
  local sets=()
  for o in "$@"; do sets+=(--set "$o"); done
  local out="$work/$kind/$name"
  rm -rf "$out"
  mkdir -p "$out"
  local t0
  t0=$(date +%s)
  set +e
  "$trace" --data "$scenes_dir/$scene" --config "$cfg" "${budget_for_run[@]}" "${sets[@]}" \
    --out "$out" --config-name "$name" --scene-name "$scene" --quiet --threads "$threads" \
    "${schedule[@]}" \
    "${extra[@]}" >"$out/log.txt" 2>&1
  local rc=$?
  set -e
  local last
  last=$(tail -n 1 "$out/log.txt")
  echo "[$kind] $name on $scene: exit $rc, $(( $(date +%s) - t0 )) s: $last"
  if [[ $rc != 0 && $rc != 3 ]]; then
    echo "run.sh: banmo_trace failed for $kind/$name (log: $out/log.txt)" >&2
    tail -n 5 "$out/log.txt" >&2
  fi
}

launch() {  # launch KIND NAME SCENE ...: run_trace, up to --jobs at a time
  local out="$work/$1/$2"
  if [[ $resume == 1 && -f "$out/done" ]]; then echo "[$1] $2: done before, kept"; return; fi
  make_scene "$3"  # in the foreground: two jobs never make one scene
  if [[ $jobs == 1 ]]; then run_trace "$@"; return; fi
  while (( $(jobs -rp | wc -l) >= jobs )); do wait -n || true; done
  run_trace "$@" &
}

if [[ $do_compare == 1 ]]; then
  budget_for_run=("${budget[@]}")
  while read -r modes _axes name overrides; do
    [[ -z "$modes" || "$modes" == \#* ]] && continue
    mode_ok "$modes" || continue
    selected "$name" || continue
    # shellcheck disable=SC2086
    launch compare "$name" "$compare_scene" "$base" -- $overrides
  done <"$here/configs.txt"
  if [[ $fox == 1 ]]; then
    budget_for_run=()
    for rule in adam lm alternate; do
      selected "fox_$rule" || continue
      rule_sets=("stages[*].step_rule=$rule")
      # alternate's per-frame blocks move only in pose solves (configs.txt);
      # fox.yaml holds the root, so they solve the bone transforms.
      [[ $rule == alternate ]] && rule_sets+=("stages[*].pose_solve.every=200"
                                              "stages[*].pose_solve.iterations=5"
                                              "stages[*].pose_solve.bones=true")
      launch fox "fox_$rule" fox "$root/problems/fox.yaml" --max-solve-seconds 1800 -- \
        "${rule_sets[@]}"
    done
  fi
fi
if [[ $do_stability == 1 ]]; then
  budget_for_run=("${budget[@]}")
  while read -r modes name scene overrides; do
    [[ -z "$modes" || "$modes" == \#* ]] && continue
    mode_ok "$modes" || continue
    selected "$name" || continue
    # shellcheck disable=SC2086
    launch stability "$name" "$scene" "$base" -- $overrides
  done <"$here/stability.txt"
fi

wait  # the last background runs (--jobs)
runs_seconds=$(( $(date +%s) - start ))
echo "[summary] plots, CSV and tables"
python3 "$here/summarize.py" --mode "$mode" --work "$work" --here "$here" \
  --results "${BANMO_BENCH_RESULTS:-$here}" --readme "${BANMO_BENCH_README:-$root/benchmarks/README.md}" \
  --run-seconds "$runs_seconds" \
  --command "bash benchmarks/solver/run.sh${args_given:+ $args_given}" \
  --setup "base \`${base#"$root"/}\` with \`${budget[*]}\`, $jobs run(s) at a time at $threads thread(s) each on $(nproc) cores"
echo "[done] run.sh ($mode) in $(( $(date +%s) - start )) s"
