// Feature-matching loss (BANMo Sec. 3.4, Eq. 17):
//   r = sqrt(w) (X_hat^*(x^t) - X^*(x^t)),   dimension 3 (canonical units),
// where X_hat^* is the canonical point matched by the pixel feature
// (soft-argmax over canonical embeddings, Eq. 15) and
// X^* = sum_i tau_i X_i^* the expected canonical surface point (Eq. 5).
#pragma once

#include <cmath>

namespace banmo {

class FeatureMatchLoss {
 public:
  static constexpr int kNumResiduals = 3;
  explicit FeatureMatchLoss(double weight) : sqrt_weight_(std::sqrt(weight)) {}

  template <typename T>
  bool operator()(const T* matched_canonical, const T* expected_canonical, T* residual) const {
    for (int k = 0; k < 3; ++k) {
      residual[k] = T(sqrt_weight_) * (matched_canonical[k] - expected_canonical[k]);
    }
    return true;
  }

 private:
  const double sqrt_weight_;
};

}  // namespace banmo
