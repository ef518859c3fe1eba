#include "banmo/losses/ray.h"

#include "banmo/losses/ray_functors.h"
#include "banmo/util/logging.h"

namespace banmo {

const char* LossTermName(LossTerm term) {
  switch (term) {
    case LossTerm::kRgb:
      return "rgb";
    case LossTerm::kSilhouette:
      return "silhouette";
    case LossTerm::kFlow:
      return "flow";
    case LossTerm::kFeatureMatch:
      return "feature_match";
    case LossTerm::kCycle2d:
      return "cycle_2d";
    case LossTerm::kCycle3d:
      return "cycle_3d";
  }
  return "unknown";
}

int LossTermResiduals(LossTerm term, int num_samples) {
  switch (term) {
    case LossTerm::kRgb:
      return RgbLoss::kNumResiduals;
    case LossTerm::kSilhouette:
      return SilhouetteLoss::kNumResiduals;
    case LossTerm::kFlow:
      return FlowLoss::kNumResiduals;
    case LossTerm::kFeatureMatch:
      return FeatureMatchLoss::kNumResiduals;
    case LossTerm::kCycle2d:
      return Cycle2dLoss::kNumResiduals;
    case LossTerm::kCycle3d:
      return Cycle3dLoss::kNumResiduals * num_samples;
  }
  return 0;
}

double RayLossWeights::Weight(LossTerm term) const {
  switch (term) {
    case LossTerm::kRgb:
      return rgb;
    case LossTerm::kSilhouette:
      return silhouette;
    case LossTerm::kFlow:
      return flow;
    case LossTerm::kFeatureMatch:
      return feature_match;
    case LossTerm::kCycle2d:
      return cycle_2d;
    case LossTerm::kCycle3d:
      return cycle_3d;
  }
  return 0.0;
}

bool Ray::HasTerm(LossTerm term, const RayLossWeights& weights) const {
  if (!(weights.Weight(term) > 0.0) || NumSamples() == 0) return false;
  const bool object = mask >= 0.5;
  switch (term) {
    case LossTerm::kRgb:
      return object;
    case LossTerm::kSilhouette:
      return mask >= 0.0;
    case LossTerm::kFlow:
      return object && has_flow && partner_frame >= 0 && partner_frame != frame;
    case LossTerm::kFeatureMatch:
    case LossTerm::kCycle2d:
      return object && has_feature;
    case LossTerm::kCycle3d:
      return true;
  }
  return false;
}

RenderLocals RenderLocals::For(const Ray& ray, const RayLossWeights& weights) {
  RenderLocals l;
  const int n = ray.NumSamples();
  l.num_samples = n;
  l.has_rgb = ray.HasTerm(LossTerm::kRgb, weights);
  l.has_displacement = ray.HasTerm(LossTerm::kFlow, weights);
  l.has_matched = ray.HasTerm(LossTerm::kFeatureMatch, weights);
  l.has_cycle = ray.HasTerm(LossTerm::kCycle2d, weights);
  int offset = 0;
  l.sdf = offset;
  offset += n;
  l.rgb = offset;
  if (l.has_rgb) offset += 3 * n;
  l.canonical = offset;
  if (l.has_matched) offset += 3 * n;  // X*_i enter the render functor only through Eq. 5
  l.displacement = offset;
  if (l.has_displacement) offset += 2 * n;
  l.log_beta = offset;
  offset += 1;
  l.matched = offset;
  if (l.has_matched) offset += 3;
  l.cycle_projection = offset;
  if (l.has_cycle) offset += 2;
  l.size = offset;
  return l;
}

}  // namespace banmo
