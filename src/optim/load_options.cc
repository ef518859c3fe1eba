#include "banmo/optim/load_options.h"

namespace banmo {

LoadOptions DatasetLoadOptions(const SolverConfig& config) {
  LoadOptions load;
  load.load_features = false;
  load.load_flow = false;
  for (const StageConfig& s : config.stages) {
    load.load_features =
        load.load_features || s.losses.feature_match.weight > 0 || s.losses.cycle_2d.weight > 0;
    load.load_flow = load.load_flow || s.losses.flow.weight > 0;
  }
  return load;
}

}  // namespace banmo
