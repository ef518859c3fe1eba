// Which parts of a dataset a solver config needs.
#pragma once

#include "banmo/io/dataset.h"
#include "banmo/optim/config.h"

namespace banmo {

// The dataset parts the stages of `config` use: features when any stage
// weights feature_match, cycle_2d or feature_render, flow when any stage
// weights flow; depth never (ground truth).
LoadOptions DatasetLoadOptions(const SolverConfig& config);

}  // namespace banmo
