// Options of automatic model sizing (config key model.auto_size; the
// algorithm is in optim/auto_size.h, docs/solver.md "Automatic model
// sizing"): start small, and at a few points of the first stage split the
// bones whose rays keep a high error, or widen the SDF and colour MLPs when
// no bone stands out.
#pragma once

#include <vector>

namespace banmo {

struct AutoSizeOptions {
  // Whether the solver grows the model (needs delta skinning off: MLP_Delta's
  // output layer has one unit per bone).
  bool enabled = false;
  // Upper bound on the number of bones B (>= model.num_bones, <= 256).
  int max_bones = 32;
  // Fractions of the FIRST stage at which a grow step is considered (each
  // in [0, 1], increasing).
  std::vector<double> grow_at = {0.4, 0.55, 0.7};
  // A bone is split when (its share of the rays' error) / (its share of the
  // rays) >= error_ratio (>= 1).
  double error_ratio = 1.5;
  // Random rays evaluated at a grow point (> 0).
  int eval_rays = 2048;
  // Upper bound on the SDF and colour MLP widths; 0 = widths never grow
  // (otherwise >= model.field.sdf_width and >= model.field.color_width).
  int max_width = 0;
};

}  // namespace banmo
