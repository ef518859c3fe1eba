#include "banmo/optim/load_options.h"

namespace banmo {

LoadOptions DatasetLoadOptions(const SolverConfig& config) {
  LoadOptions load;
  load.load_features = false;
  load.load_flow = false;
  for (const StageConfig& s : config.stages) {
    load.load_features = load.load_features || s.losses[LossTerm::kFeatureMatch].weight > 0 ||
                         s.losses[LossTerm::kCycle2d].weight > 0 ||
                         s.losses[LossTerm::kFeatureRender].weight > 0;
    load.load_flow = load.load_flow || s.losses[LossTerm::kFlow].weight > 0;
  }
  return load;
}

}  // namespace banmo
