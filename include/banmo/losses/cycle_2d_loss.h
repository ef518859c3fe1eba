// 2D cycle-consistency loss (BANMo Sec. 3.4, Eq. 18):
//   r = sqrt(w) (Pi^t(W^{t,->}(X_hat^*(x^t))) - x^t),   dimension 2 (pixels),
// the matched canonical point pushed forward to frame t and projected must
// land on the pixel it was matched from.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace banmo {

class Cycle2dLoss {
 public:
  static constexpr int kNumResiduals = 2;
  Cycle2dLoss(const Eigen::Vector2d& pixel, double weight)
      : pixel_(pixel), sqrt_weight_(std::sqrt(weight)) {}

  // projected: Pi^t(W^{t,->}(X_hat^*)), pixels.
  template <typename T>
  bool operator()(const T* projected, T* residual) const {
    residual[0] = T(sqrt_weight_) * (projected[0] - T(pixel_[0]));
    residual[1] = T(sqrt_weight_) * (projected[1] - T(pixel_[1]));
    return true;
  }

 private:
  const Eigen::Vector2d pixel_;
  const double sqrt_weight_;
};

}  // namespace banmo
