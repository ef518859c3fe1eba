// Helpers for the residual-level regression tests: evaluate a cost function
// and compare Jacobians.
#pragma once

#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

namespace banmo::testing {

using Rows = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Evaluation {
  Eigen::VectorXd residuals;
  std::vector<Rows> jacobians;  // one per parameter block
  bool ok = false;
};

inline Evaluation EvaluateCost(const ceres::CostFunction& cost,
                               const std::vector<double*>& parameters) {
  Evaluation e;
  const int rows = cost.num_residuals();
  e.residuals.resize(rows);
  const auto& sizes = cost.parameter_block_sizes();
  e.jacobians.resize(sizes.size());
  std::vector<double*> jac_ptrs(sizes.size());
  for (size_t i = 0; i < sizes.size(); ++i) {
    e.jacobians[i].setZero(rows, sizes[i]);
    jac_ptrs[i] = e.jacobians[i].data();
  }
  e.ok = cost.Evaluate(parameters.data(), e.residuals.data(), jac_ptrs.data());
  return e;
}

// Largest absolute entry over all Jacobian blocks.
inline double MaxAbs(const Evaluation& e) {
  double m = 0.0;
  for (const Rows& j : e.jacobians) m = std::max(m, j.cwiseAbs().maxCoeff());
  return m;
}

// max |a - b| over all blocks, divided by the largest entry of b.
inline double RelativeJacobianError(const Evaluation& a, const Evaluation& b) {
  double err = 0.0;
  for (size_t i = 0; i < a.jacobians.size(); ++i) {
    err = std::max(err, (a.jacobians[i] - b.jacobians[i]).cwiseAbs().maxCoeff());
  }
  const double scale = MaxAbs(b);
  return scale > 0 ? err / scale : err;
}

inline bool AllFinite(const Evaluation& e) {
  if (!e.residuals.allFinite()) return false;
  for (const Rows& j : e.jacobians) {
    if (!j.allFinite()) return false;
  }
  return true;
}

}  // namespace banmo::testing
