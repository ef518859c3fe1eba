// Bones-inside-surface regulariser (BANMo keeps bone centres inside the
// shape): for each rest bone centre C_b,
//   r_b = sqrt(w) max(0, sdf(C_b) + margin),   dimension 1 (canonical units),
// zero when the centre is at least `margin` inside the surface (sdf < 0
// inside). The hinge has a one-sided derivative at 0, like Ceres' own
// bounds; that point is measure-zero in practice.
#pragma once

#include <cmath>

namespace banmo {

class BoneInsideLoss {
 public:
  static constexpr int kNumResiduals = 1;
  BoneInsideLoss(double margin, double weight) : margin_(margin), sqrt_weight_(std::sqrt(weight)) {}

  template <typename T>
  bool operator()(const T* sdf_at_centre, T* residual) const {
    const T v = sdf_at_centre[0] + T(margin_);
    residual[0] = v > T(0) ? T(sqrt_weight_) * v : T(0) * v;
    return true;
  }

 private:
  const double margin_;
  const double sqrt_weight_;
};

}  // namespace banmo
