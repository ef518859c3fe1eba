#include "banmo/volume/volume_rendering.h"

#include <cmath>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

RaySamples StratifiedSamples(int num_samples, double near, double far, double dir_norm, bool jitter,
                             std::mt19937* rng) {
  CHECK_GT(num_samples, 0);
  // Non-finite or crossed planes come from non-finite poses or bounds (a
  // diverged solve), not from a bug here: the solver's guard reports them.
  if (!(std::isfinite(near) && std::isfinite(far) && near < far)) {
    ThrowDivergenceError("near/far planes (", near, ", ", far,
                         ") of a ray are not finite and increasing");
  }
  RaySamples s;
  s.depths.resize(num_samples);
  s.deltas.resize(num_samples);
  s.dir_norm = dir_norm;
  const double bin = (far - near) / num_samples;
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int i = 0; i < num_samples; ++i) {
    const double u = (jitter && rng != nullptr) ? uniform(*rng) : 0.5;
    s.depths[i] = near + (i + u) * bin;
  }
  for (int i = 0; i < num_samples; ++i) {
    const double next = (i + 1 < num_samples) ? s.depths[i + 1] : far;
    s.deltas[i] = std::max(next - s.depths[i], 1e-6 * bin) * dir_norm;
  }
  return s;
}

}  // namespace banmo
