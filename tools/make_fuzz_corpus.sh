#!/usr/bin/env bash
# Seed corpora for the fuzz targets (fuzz/), made from a small synthetic
# dataset and a two-batch solve, so nothing binary is committed.
#   bash tools/make_fuzz_corpus.sh BANMO_BINARY OUT_DIR
# OUT_DIR/<target>/ gets the seeds of each target (fuzz/*.cc say what the
# input is; a leading selector byte where a target takes several kinds).
set -euo pipefail
banmo="$1"
out="$2"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"
for t in manifest pose npy png config gltf mesh model state; do mkdir -p "$out/fuzz_$t"; done

"$banmo" synth --videos 1 --frames 3 --size 32 --gaps 1 --threads 1 --out "$work/ds" >/dev/null
v="$work/ds/video_000"
cp "$work/ds/manifest.yaml" "$out/fuzz_manifest/manifest.yaml"
cp "$v/root_poses_init.txt" "$out/fuzz_pose/init.txt"
cp "$v/root_poses_gt.txt" "$out/fuzz_pose/gt.txt"
cp "$v/features/00000.npy" "$out/fuzz_npy/features.npy"
# PNG: selector byte 0 RGB, 1 mask, 2 KITTI flow, 3 depth.
{ printf '\x00'; cat "$v/rgb/00000.png"; } >"$out/fuzz_png/rgb"
{ printf '\x01'; cat "$v/mask/00000.png"; } >"$out/fuzz_png/mask"
{ printf '\x02'; cat "$v/flow/fw_1/00000.png"; } >"$out/fuzz_png/flow"
{ printf '\x03'; cat "$v/depth/00000.png"; } >"$out/fuzz_png/depth"
for f in "$root"/problems/*.yaml; do cp "$f" "$out/fuzz_config/$(basename "$f")"; done
# glTF: selector byte 0 .glb, 1 .gltf.
fox="$root/../shared/data/gltf/Fox/Fox.glb"
if [ -f "$fox" ]; then { printf '\x00'; cat "$fox"; } >"$out/fuzz_gltf/fox"; fi
# Mesh: selector byte 0 .ply, 1 .obj.
{ printf '\x00'; cat "$v/gt_mesh/00000.ply"; } >"$out/fuzz_mesh/gt"
printf '\x01v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' >"$out/fuzz_mesh/triangle"

cat >"$work/two.yaml" <<'YAML'
model:
  num_bones: 2
  field: {sdf_width: 8, color_width: 8, embedding_width: 8}
defaults: {batch_rays: 16, samples_per_ray: 4, sampling: {flow_gaps: [1]}}
stages: [{name: one, batches: 3}]
YAML
"$banmo" solve --data "$work/ds" --config "$work/two.yaml" --out "$work/solve" --no-extract \
  --no-eval --quiet --threads 1 --stop-after-batches 2 >/dev/null
ck="$work/solve/checkpoint"
# Model: 4-byte little-endian length of model.yaml, model.yaml, params.bin.
python3 - "$ck" "$out/fuzz_model/checkpoint" <<'PY'
import struct, sys
yaml = open(sys.argv[1] + "/model.yaml", "rb").read()
params = open(sys.argv[1] + "/params.bin", "rb").read()
open(sys.argv[2], "wb").write(struct.pack("<I", len(yaml)) + yaml + params)
PY
cp "$ck/state.bin" "$out/fuzz_state/state.bin"
echo "seed corpora in $out: $(find "$out" -type f | wc -l) files"
