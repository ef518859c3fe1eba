// What `banmo solve` writes after its stages: meshes (banmo extract's files)
// and, when the dataset has ground-truth meshes, their evaluation. Glue
// between library calls only.
#pragma once

#include <string>

#include "banmo/io/dataset.h"
#include "banmo/io/holdout.h"
#include "banmo/model/model.h"

namespace banmo {

// Writes OUT/meshes (docs/extract.md) at the given marching-cubes resolution
// within `bounds_min/max`; with `evaluate` and ground truth present, writes
// OUT/eval (docs/eval.md, banmo protocol) and prints the table.
void WriteSolveOutputs(const Model& model, const Dataset& dataset, const std::string& out_dir,
                       int resolution, bool evaluate);

// The --holdout-every of a solve in `out_dir`: the flag's value (0 = none)
// for a new solve, which is recorded in OUT/holdout.yaml; a --resume takes
// the recorded one and refuses another (InputError naming the file).
int ResolveHoldoutEvery(const std::string& out_dir, bool resume, bool given, int every);

// After the stages: the held-out frames get their neighbours' interpolated
// transforms (visualize/holdout.h), also in OUT/checkpoint (so render,
// export and extract show them); their meshes are then what WriteSolveOutputs
// extracts.
void InterpolateHeldOutFramesInCheckpoint(const HoldoutPlan& plan, const std::string& out_dir,
                                          Model* model);

// Renders the held-out frames into OUT/holdout (frames/, errors/,
// frames.csv, summary.json) and prints their mean mask IoU and PSNR.
void WriteHoldoutScore(const Model& model, const Dataset& dataset, const HoldoutPlan& plan,
                       const std::string& out_dir);

}  // namespace banmo
