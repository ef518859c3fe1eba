// Test helpers for the field module: a chunked full-Jet Jacobian and a scaled
// error. (Jacobian-vector products are differentiated wrt parameters with
// banmo::Dual over Jets, include/banmo/util/dual.h.)
#pragma once

#include <ceres/jet.h>

#include <Eigen/Core>
#include <algorithm>
#include <vector>

namespace banmo::test {

// Full Jacobian (out_dim x x.size()) of f(const Jet* x, Jet* out), in chunks
// of N derivative slots (Jet<double, N>), so large parameter blocks work.
template <int N, typename F>
Eigen::MatrixXd JetJacobian(const F& f, const Eigen::VectorXd& x, int out_dim) {
  using J = ceres::Jet<double, N>;
  const int n = static_cast<int>(x.size());
  Eigen::MatrixXd jac(out_dim, n);
  std::vector<J> xj(n), out(out_dim);
  for (int c0 = 0; c0 < n; c0 += N) {
    for (int i = 0; i < n; ++i) {
      xj[i] = J(x[i]);
      if (i >= c0 && i < c0 + N) xj[i].v[i - c0] = 1.0;
    }
    f(xj.data(), out.data());
    for (int r = 0; r < out_dim; ++r) {
      for (int i = c0; i < std::min(n, c0 + N); ++i) jac(r, i) = out[r].v[i - c0];
    }
  }
  return jac;
}

// Max |a - b| / max(1, max |b|): relative to the reference's scale.
inline double ScaledError(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
}

}  // namespace banmo::test
