#include "banmo/registration/bone_registration_config.h"

namespace banmo {

BoneRegistrationConfig BoneRegistrationConfig::AfterLastBatch() const {
  BoneRegistrationConfig out = *this;
  out.match_weight = after_last_batch.match_weight.value_or(match_weight);
  out.mask_weight = after_last_batch.mask_weight.value_or(mask_weight);
  out.coverage_weight = after_last_batch.coverage_weight.value_or(coverage_weight);
  return out;
}

void BoneRegistrationConfig::Check(const OptionChecker& c, const std::string& r) const {
  c.IncreasingFractions(r + ".at", at);
  c.Positive(r + ".resolution", resolution);
  c.Positive(r + ".vertices", vertices);
  c.Positive(r + ".match_pixels", match_pixels);
  c.Positive(r + ".match_weight", match_weight);
  c.Positive(r + ".huber_px", huber_px);
  c.NonNegative(r + ".joint_weight", joint_weight);
  c.Fraction(r + ".joint_min_weight", joint_min_weight);
  c.NonNegative(r + ".joint_points", joint_points);
  c.NonNegative(r + ".smooth_weight", smooth_weight);
  c.NonNegative(r + ".rest_weight", rest_weight);
  c.Positive(r + ".visible_tolerance", visible_tolerance);
  c.Positive(r + ".iterations", iterations);
  c.NonNegative(r + ".mask_weight", mask_weight);
  c.Positive(r + ".mask_points", mask_points);
  c.NonNegative(r + ".coverage_weight", coverage_weight);
  c.Positive(r + ".coverage_pixels", coverage_pixels);
  c.Positive(r + ".coverage_rounds", coverage_rounds);
  const BoneRegistrationFinalWeights& last = after_last_batch;
  if (last.match_weight) c.Positive(r + ".after_last_batch.match_weight", *last.match_weight);
  if (last.mask_weight) c.NonNegative(r + ".after_last_batch.mask_weight", *last.mask_weight);
  if (last.coverage_weight) {
    c.NonNegative(r + ".after_last_batch.coverage_weight", *last.coverage_weight);
  }
}

}  // namespace banmo
