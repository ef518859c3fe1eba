// One sampled pixel ray of a minibatch and the per-ray loss terms.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "banmo/render/volume_rendering.h"

namespace banmo {

// The loss terms evaluated per ray. Each active term of a ray becomes one
// Ceres residual block (so each term has its own robust loss and carries only
// the parameter blocks it depends on); all of a ray's terms share one batched
// evaluation (losses/ray_batch.h).
enum class LossTerm { kRgb = 0, kSilhouette, kFlow, kFeatureMatch, kCycle2d, kCycle3d };
inline constexpr int kNumLossTerms = 6;
// Terms computed by the ray render functor (all but kCycle3d).
inline constexpr int kNumRenderTerms = 5;

const char* LossTermName(LossTerm term);  // "rgb", "silhouette", "flow", ...
// Residuals of a term for a ray with `num_samples` samples.
int LossTermResiduals(LossTerm term, int num_samples);

// Weight of each loss term; 0 switches a term off.
struct RayLossWeights {
  double rgb = 1.0;            // L_rgb, colour in [0, 1]
  double silhouette = 1.0;     // L_sil
  double flow = 0.01;          // L_OF (pixels^2)
  double feature_match = 1.0;  // L_match (Eq. 17), canonical units^2
  double cycle_2d = 0.01;      // L_2D-cyc (Eq. 18), pixels^2
  double cycle_3d = 1.0;       // L_3D-cyc (Eq. 19), scene units^2

  double Weight(LossTerm term) const;
};

// Observations and constants of one ray (data, never optimised).
struct Ray {
  int video = 0;
  int frame = 0;
  int partner_frame = -1;  // frame t' of the flow term (same video), -1 = none
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();   // pixel position (camera.h convention)
  Eigen::Vector3d rgb = Eigen::Vector3d::Zero();  // observed colour in [0, 1]
  double mask = -1.0;  // 1 object, 0 background, < 0 unknown (no silhouette term)
  bool has_flow = false;
  Eigen::Vector2d flow = Eigen::Vector2d::Zero();  // observed flow t -> t' (pixels)
  bool has_feature = false;
  Eigen::Matrix<double, 16, 1> feature = Eigen::Matrix<double, 16, 1>::Zero();
  // Grid points of the feature match's truncated soft-argmax (Eq. 15),
  // chosen once per minibatch (the top-K most similar) and then held fixed.
  std::vector<int> match_indices;
  RaySamples samples;  // stratified depths and interval lengths
  // tau_i of the 3D cycle (Eq. 19, "tau as constant weight"): the rendering
  // weights at the parameters of the minibatch's start, held fixed during
  // the minibatch so the residual is a function of the parameters and its
  // Jacobian exact. Filled by RayBatch::SetRays when empty.
  std::vector<double> cycle_tau;

  int NumSamples() const { return static_cast<int>(samples.depths.size()); }
  // Whether `term` contributes residuals for this ray under `weights`.
  bool HasTerm(LossTerm term, const RayLossWeights& weights) const;
};

}  // namespace banmo
