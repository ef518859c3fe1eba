// One sampled pixel ray of a minibatch and the per-ray loss terms.
#pragma once

#include <Eigen/Core>
#include <array>
#include <initializer_list>
#include <string>
#include <vector>

#include "banmo/losses/loss_table.h"
#include "banmo/volume/volume_rendering.h"

namespace banmo {

// Weight of each per-ray loss term (losses/loss_table.h); 0 switches a term
// off. Defaults: the table's.
class RayLossWeights {
 public:
  RayLossWeights();
  explicit RayLossWeights(const std::array<double, kNumRayTerms>& weights) : w_(weights) {}
  // Weight 1 for the `enabled` terms, 0 for all others.
  static RayLossWeights Only(std::initializer_list<LossTerm> enabled);

  double& operator[](LossTerm term) { return w_.at(static_cast<size_t>(term)); }
  double operator[](LossTerm term) const { return w_.at(static_cast<size_t>(term)); }
  double Weight(LossTerm term) const { return (*this)[term]; }

 private:
  std::array<double, kNumRayTerms> w_;
};

// Observations and constants of one ray (data, never optimised).
struct Ray {
  int video = 0;
  int frame = 0;
  int partner_frame = -1;  // frame t' of the flow term (same video), -1 = none
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();   // pixel position (camera.h convention)
  Eigen::Vector3d rgb = Eigen::Vector3d::Zero();  // observed colour in [0, 1]
  double mask = -1.0;  // 1 object, 0 background, < 0 unknown (no silhouette term)
  // Factor on the silhouette term's weight: the pixel's importance weight
  // under sampling.unbiased_silhouette (RaySampler::PixelWeight), else 1.
  double silhouette_weight = 1.0;
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
  // Jacobian exact. Filled by RayBatch::SetRays when empty (and the batch
  // holds them, RayBatchOptions::hold_cycle_tau); empty: each evaluation's
  // own values, without their derivative.
  std::vector<double> cycle_tau;

  int NumSamples() const { return static_cast<int>(samples.depths.size()); }
  // Whether `term` contributes residuals for this ray under `weights`.
  bool HasTerm(LossTerm term, const RayLossWeights& weights) const;
};

}  // namespace banmo
