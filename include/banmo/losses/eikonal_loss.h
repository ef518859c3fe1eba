// Eikonal regulariser (VolSDF/IGR; BANMo's SDF field, Sec. 3.1):
//   r = sqrt(w) (||grad_X sdf(X)|| - 1),   dimension 1,
// at canonical points X sampled in the canonical bounds (constants), so the
// residual depends on the SDF MLP weights only. The norm is computed as
// sqrt(|g|^2 + eps^2) with eps = 1e-12 so a zero gradient gives a finite
// Jacobian.
#pragma once

#include <cmath>

namespace banmo {

class EikonalLoss {
 public:
  static constexpr int kNumResiduals = 1;
  explicit EikonalLoss(double weight) : sqrt_weight_(std::sqrt(weight)) {}

  template <typename T>
  bool operator()(const T* sdf_gradient, T* residual) const {
    using std::sqrt;
    const T norm = sqrt(sdf_gradient[0] * sdf_gradient[0] + sdf_gradient[1] * sdf_gradient[1] +
                        sdf_gradient[2] * sdf_gradient[2] + T(1e-24));
    residual[0] = T(sqrt_weight_) * (norm - T(1));
    return true;
  }

 private:
  const double sqrt_weight_;
};

}  // namespace banmo
