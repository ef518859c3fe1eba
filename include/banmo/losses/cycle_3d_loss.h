// 3D cycle-consistency loss (BANMo Sec. 3.4, Eq. 19), per ray sample i:
//   r_i = sqrt(w tau_i) (W^{t,->}(W^{t,<-}(X_i^t)) - X_i^t),   dimension 3,
// backward to canonical, then forward back (docs/design.md: the reading of the
// paper's slip), with tau_i a constant weight (no gradient through it).
// X_i^t and the cycled point are in camera coordinates of frame t.
// A sample whose weight is below kMinWarpTau counts as weight 0
// (losses/sample_weight.h).
#pragma once

#include <cmath>

#include "banmo/losses/sample_weight.h"

namespace banmo {

class Cycle3dLoss {
 public:
  static constexpr int kNumResiduals = 3;
  // tau: the sample's rendering weight, held constant.
  Cycle3dLoss(double tau, double weight)
      : sqrt_weight_tau_(WarpsSample(tau) ? std::sqrt(weight * tau) : 0.0) {}

  // False when the residual is 0 whatever the points (weight or tau 0).
  bool active() const { return sqrt_weight_tau_ > 0.0; }

  template <typename T>
  bool operator()(const T* cycled_point, const T* sample_point, T* residual) const {
    for (int k = 0; k < 3; ++k) {
      residual[k] = T(sqrt_weight_tau_) * (cycled_point[k] - sample_point[k]);
    }
    return true;
  }

 private:
  const double sqrt_weight_tau_;
};

}  // namespace banmo
