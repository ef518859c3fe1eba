// Silhouette loss (BANMo Sec. 3.4, L_sil): r = sqrt(w) (o(x^t) - s_hat(x^t)),
// with o = sum_i tau_i the rendered opacity (Eq. 4) and s_hat in {0, 1} the
// observed mask (pixels marked "ignore" get no residual). Dimension 1.
#pragma once

#include <cmath>

namespace banmo {

class SilhouetteLoss {
 public:
  static constexpr int kNumResiduals = 1;
  SilhouetteLoss(double observed_mask, double weight)
      : observed_(observed_mask), sqrt_weight_(std::sqrt(weight)) {}

  template <typename T>
  bool operator()(const T* opacity, T* residual) const {
    residual[0] = T(sqrt_weight_) * (opacity[0] - T(observed_));
    return true;
  }

 private:
  const double observed_;
  const double sqrt_weight_;
};

}  // namespace banmo
