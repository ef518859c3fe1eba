#include "banmo/losses/ray.h"

#include "banmo/field/canonical_field.h"
#include "banmo/field/embedding_match.h"
#include "banmo/losses/bone_inside_loss.h"
#include "banmo/losses/eikonal_loss.h"
#include "banmo/losses/pose_smoothness_loss.h"
#include "banmo/losses/ray_functors.h"
#include "banmo/util/logging.h"

namespace banmo {

// The table's residual counts are the functors' (one place to read them,
// checked here where the functors are known).
static_assert(LossInfo(LossTerm::kRgb).residuals == RgbLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kSilhouette).residuals == SilhouetteLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kFlow).residuals == FlowLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kFeatureMatch).residuals == FeatureMatchLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kCycle2d).residuals == Cycle2dLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kFeatureRender).residuals == FeatureRenderLoss::kNumResiduals);
static_assert(CompositeLocals::kEmbeddingDim == CanonicalField::EmbeddingDim() &&
              CompositeLocals::kEmbeddingDim == kEmbeddingFeatureDim);
static_assert(LossInfo(LossTerm::kCycle3d).residuals == Cycle3dLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kEikonal).residuals == EikonalLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kBoneInside).residuals == BoneInsideLoss::kNumResiduals);
static_assert(LossInfo(LossTerm::kPoseSmoothness).residuals == PoseSmoothnessLoss::kNumResiduals);

RayLossWeights::RayLossWeights() {
  for (int t = 0; t < kNumRayTerms; ++t) w_[t] = kLossTable[t].default_weight;
}

RayLossWeights RayLossWeights::Only(std::initializer_list<LossTerm> enabled) {
  RayLossWeights w(std::array<double, kNumRayTerms>{});
  for (LossTerm term : enabled) w[term] = 1.0;
  return w;
}

bool Ray::HasTerm(LossTerm term, const RayLossWeights& weights) const {
  if (!IsRayTerm(term) || !(weights[term] > 0.0) || NumSamples() == 0) return false;
  const bool object = mask >= 0.5;
  switch (LossInfo(term).rays) {
    case RaySelect::kNotPerRay:
      return false;
    case RaySelect::kKnownMask:
      return mask >= 0.0;
    case RaySelect::kObject:
      return object;
    case RaySelect::kObjectWithFlow:
      return object && has_flow && partner_frame >= 0 && partner_frame != frame;
    case RaySelect::kObjectWithFeature:
      return object && has_feature;
    case RaySelect::kAll:
      return true;
  }
  return false;
}

CompositeLocals CompositeLocals::For(const Ray& ray, const RayLossWeights& weights) {
  CompositeLocals l;
  const int n = ray.NumSamples();
  l.num_samples = n;
  l.has_rgb = ray.HasTerm(LossTerm::kRgb, weights);
  l.has_displacement = ray.HasTerm(LossTerm::kFlow, weights);
  l.has_matched = ray.HasTerm(LossTerm::kFeatureMatch, weights);
  l.has_cycle = ray.HasTerm(LossTerm::kCycle2d, weights);
  l.has_embedding = ray.HasTerm(LossTerm::kFeatureRender, weights);
  int offset = 0;
  l.sdf = offset;
  offset += n;
  l.rgb = offset;
  if (l.has_rgb) offset += 3 * n;
  l.canonical = offset;
  if (l.has_matched) offset += 3 * n;  // X*_i enter the composite functor only through Eq. 5
  l.displacement = offset;
  if (l.has_displacement) offset += 2 * n;
  l.log_beta = offset;
  offset += 1;
  l.matched = offset;
  if (l.has_matched) offset += 3;
  l.cycle_projection = offset;
  if (l.has_cycle) offset += 2;
  l.embedding = offset;
  if (l.has_embedding) offset += kEmbeddingDim * n;
  l.size = offset;
  return l;
}

}  // namespace banmo
