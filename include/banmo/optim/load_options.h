// Which parts of a dataset a solver config needs.
#pragma once

#include "banmo/io/dataset.h"
#include "banmo/optim/config.h"

namespace banmo {

// The dataset parts the stages of `config` use: features when any stage
// weights feature_match or cycle_2d, flow when any stage weights flow; depth
// never (ground truth).
LoadOptions DatasetLoadOptions(const SolverConfig& config);

}  // namespace banmo
