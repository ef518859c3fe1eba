// Temporal smoothness of pose tracks (regulariser; BANMo obtains smooth
// tracks through its Fourier pose codes, Sec. 3.2 Eq. 12; with explicit
// per-frame SE(3) blocks we penalise consecutive differences instead):
//   r = [sqrt(w_rot) Log(R_a^T R_b);  sqrt(w_trans) (t_b - t_a)],   dim 6,
// for two poses a = frame t, b = frame t+1 (geometry/se3.h storage). Log is
// the rotation vector (radians) of the relative quaternion, computed with
// ceres::QuaternionToAngleAxis (finite at the identity). The relative
// quaternion's sign is flipped to the short way round.
#pragma once

#include <ceres/rotation.h>

#include <cmath>

#include "banmo/geometry/se3.h"

namespace banmo {

class PoseSmoothnessLoss {
 public:
  static constexpr int kNumResiduals = 6;
  PoseSmoothnessLoss(double rotation_weight, double translation_weight)
      : sqrt_w_rot_(std::sqrt(rotation_weight)), sqrt_w_trans_(std::sqrt(translation_weight)) {}

  template <typename T>
  bool operator()(const T* pose_a, const T* pose_b, T* residual) const {
    const T conj_a[4] = {pose_a[0], -pose_a[1], -pose_a[2], -pose_a[3]};
    T rel[4];
    ceres::QuaternionProduct(conj_a, pose_b + kPoseQw, rel);
    if (rel[0] < T(0)) {
      for (T& v : rel) v = -v;
    }
    ceres::QuaternionToAngleAxis(rel, residual);
    for (int k = 0; k < 3; ++k) {
      residual[k] *= T(sqrt_w_rot_);
      residual[3 + k] = T(sqrt_w_trans_) * (pose_b[kPoseT + k] - pose_a[kPoseT + k]);
    }
    return true;
  }

 private:
  const double sqrt_w_rot_;
  const double sqrt_w_trans_;
};

}  // namespace banmo
