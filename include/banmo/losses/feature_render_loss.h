// Rendered-embedding loss (the official BANMo implementation's `frnd` term,
// nnutils/rendering.py; the paper's Eq. 15 embedding, rendered as in Eq. 4):
//   r = sqrt(w) (e / |e| - f),   e = sum_i tau_i psi(X*_i),
// dimension 16: the canonical embedding psi rendered along the ray and
// normalised, against the pixel's (unit) feature f. Unlike the feature
// match (Eq. 17), whose soft-argmax over a grid trains the embedding only
// through its ranking, this term ties the embedding to the features
// themselves and gives every object pixel a dense correspondence signal:
// its gradient moves the samples (root pose, bones) and the density towards
// the canonical points whose embedding the pixel shows. Applied on object
// pixels with a feature.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace banmo {

class FeatureRenderLoss {
 public:
  static constexpr int kNumResiduals = 16;
  // |e| is floored smoothly: sqrt(|e|^2 + kNormFloor^2). A rendered embedding
  // of norm 0 (a ray through empty space with a zero embedding) then gives
  // r = -sqrt(w) f with finite derivatives; 1e-6 is far below the norms a
  // trained or initialised embedding renders on object pixels (~0.1-1).
  static constexpr double kNormFloor = 1e-6;

  FeatureRenderLoss(const Eigen::Matrix<double, 16, 1>& feature, double weight)
      : feature_(feature), sqrt_weight_(std::sqrt(weight)) {}

  // rendered: 16 values, sum_i tau_i psi_i.
  template <typename T>
  bool operator()(const T* rendered, T* residual) const {
    using std::sqrt;
    T sq(kNormFloor * kNormFloor);
    for (int k = 0; k < kNumResiduals; ++k) sq += rendered[k] * rendered[k];
    const T inv_norm = T(1) / sqrt(sq);
    for (int k = 0; k < kNumResiduals; ++k) {
      residual[k] = T(sqrt_weight_) * (rendered[k] * inv_norm - T(feature_[k]));
    }
    return true;
  }

 private:
  const Eigen::Matrix<double, 16, 1> feature_;
  const double sqrt_weight_;
};

}  // namespace banmo
