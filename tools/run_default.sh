#!/usr/bin/env bash
# README command 1, the main job on a built-in scene: installs what is
# missing, builds `banmo`, renders the default procedural scene (the
# quadruped, 5 videos), reconstructs it with problems/default.yaml and prints
# Chamfer distance and F-score against the ground truth.
# Outputs go to runs/default/ (BANMO_OUT overrides): data/, solve/ with
# config.yaml, checkpoint/, meshes/ and eval/.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${BANMO_OUT:-$root/runs/default}"
bash "$root/tools/install_deps.sh"
echo "[build] banmo (Release)"
bash "$root/tools/build.sh" banmo
banmo="${BANMO_BUILD_DIR:-$root/build}/bin/banmo"
start=$(date +%s)
"$banmo" synth --rig quadruped --videos 5 --frames 24 --size 128 --seed 0 \
  --out "$out/data" --overwrite
"$banmo" check "$out/data"
"$banmo" solve --data "$out/data" --config "$root/problems/default.yaml" \
  --out "$out/solve" --overwrite --resolution 128
echo "[done] synth + solve + eval in $(( $(date +%s) - start )) s; outputs in $out"
