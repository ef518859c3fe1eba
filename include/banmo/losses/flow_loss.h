// Optical-flow loss (BANMo Sec. 3.1 Eqs. 6-7 and Sec. 3.4 Eq. 16):
//   F(x^t, t->t') = x^{t'} - x^t,
//   x^{t'} = sum_i tau_i Pi^{t'}(W^{t',->}(X_i^*))  + (1 - o) x^t,
//   r = sqrt(w) (F - F_hat),   dimension 2 (pixels).
// Eq. 6 pushes X_i^* with the forward warp of t' (docs/design.md: the reading of the
// paper's slip). The (1 - o) x^t term lets transparent rays predict zero
// flow; on object pixels o ~ 1 and it vanishes. The caller passes the
// expected displacement sum_i tau_i (x_i^{t'} - x^t).
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace banmo {

class FlowLoss {
 public:
  static constexpr int kNumResiduals = 2;
  FlowLoss(const Eigen::Vector2d& observed_flow, double weight)
      : observed_(observed_flow), sqrt_weight_(std::sqrt(weight)) {}

  // expected_displacement: sum_i tau_i (x_i^{t'} - x^t), pixels.
  template <typename T>
  bool operator()(const T* expected_displacement, T* residual) const {
    residual[0] = T(sqrt_weight_) * (expected_displacement[0] - T(observed_[0]));
    residual[1] = T(sqrt_weight_) * (expected_displacement[1] - T(observed_[1]));
    return true;
  }

 private:
  const Eigen::Vector2d observed_;
  const double sqrt_weight_;
};

}  // namespace banmo
