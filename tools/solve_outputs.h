// What `banmo solve` writes after its stages: meshes (banmo extract's files)
// and, when the dataset has ground-truth meshes, their evaluation. Glue
// between library calls only.
#pragma once

#include <string>

#include "banmo/io/dataset.h"
#include "banmo/model/model.h"

namespace banmo {

// Writes OUT/meshes (docs/extract.md) at the given marching-cubes resolution
// within `bounds_min/max`; with `evaluate` and ground truth present, writes
// OUT/eval (docs/eval.md, banmo protocol) and prints the table.
void WriteSolveOutputs(const Model& model, const Dataset& dataset, const std::string& out_dir,
                       int resolution, bool evaluate);

}  // namespace banmo
