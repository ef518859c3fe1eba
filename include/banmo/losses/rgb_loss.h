// Colour reconstruction loss (BANMo, Yang et al. CVPR 2022, Sec. 3.4,
// L_rgb): r = sqrt(w) (c(x^t) - c_hat(x^t)), with c(x^t) = sum_i tau_i c_i
// the rendered colour (Eq. 4) and c_hat the observed colour, both RGB in
// [0, 1]. Residual dimension 3 (colour units). Applied on object pixels.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace banmo {

class RgbLoss {
 public:
  static constexpr int kNumResiduals = 3;
  RgbLoss(const Eigen::Vector3d& observed_rgb, double weight)
      : observed_(observed_rgb), sqrt_weight_(std::sqrt(weight)) {}

  // rendered_rgb: 3 values, sum_i tau_i c_i.
  template <typename T>
  bool operator()(const T* rendered_rgb, T* residual) const {
    for (int k = 0; k < 3; ++k) residual[k] = T(sqrt_weight_) * (rendered_rgb[k] - T(observed_[k]));
    return true;
  }

 private:
  const Eigen::Vector3d observed_;
  const double sqrt_weight_;
};

}  // namespace banmo
