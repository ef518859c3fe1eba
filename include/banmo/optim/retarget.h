// Retargeting (`banmo solve --retarget DIR`; docs/solver.md, "Retargeting"):
// the shared blocks of an earlier solve's model (shape, colour, embedding,
// beta, rest bones, MLP_Delta) are copied into a model of another dataset and
// held constant in every stage, so the solver fits only that dataset's
// videos (their poses, appearance and intrinsics as the stages say).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "banmo/model/model.h"
#include "banmo/model/parameter_group.h"
#include "banmo/optim/config.h"
#include "banmo/optim/solver.h"

namespace banmo {

// The groups a retargeted solve holds constant in every stage.
std::vector<ParameterGroup> RetargetConstantGroups();

// Before the model is made: a retargeted model keeps the source's bone count
// and MLP widths, so automatic sizing is switched off. True when it was on
// (the sizes then come from the source: LoadRetargetSource).
bool SwitchOffAutoSizeForRetarget(SolverConfig* config);

// The source model in `dir` (a model folder, e.g. OUT/checkpoint of an
// earlier solve; InputError naming it when it does not load). With
// `sized_from_source` *options take its bone count and MLP widths.
std::unique_ptr<Model> LoadRetargetSource(const std::string& dir, bool sized_from_source,
                                          ModelOptions* options);

// Copies the source's shared blocks into `model` (CopySharedParameters,
// model/make_model.h: `model` takes the source's scene scale and canonical
// origin; `dir` names the source in errors) and holds them constant in
// every stage (options->extra_constant).
void ApplyRetarget(const Model& source, const std::string& dir, Model* model,
                   SolveOptions* options);

}  // namespace banmo
