// Test helpers for the field module: a forward-mode dual number over any
// scalar (to differentiate Jacobian-vector products wrt parameters with Jets,
// since nested ceres::Jets do not mix with double constants), and a chunked
// full-Jet Jacobian.
#pragma once

#include <ceres/jet.h>

#include <Eigen/Core>
#include <cmath>
#include <vector>

namespace banmo::test {

// x = v + eps d with eps^2 = 0, over a scalar S (double or ceres::Jet).
template <typename S>
struct Dual {
  S v;
  S d;
  Dual() : v(0.0), d(0.0) {}
  Dual(double x) : v(x), d(0.0) {}    // NOLINT: implicit like Jet
  Dual(const S& x) : v(x), d(0.0) {}  // NOLINT
  Dual(const S& x, const S& dx) : v(x), d(dx) {}
  Dual& operator+=(const Dual& o) {
    v += o.v;
    d += o.d;
    return *this;
  }
};

template <typename S>
Dual<S> operator+(const Dual<S>& a, const Dual<S>& b) {
  return {a.v + b.v, a.d + b.d};
}
template <typename S>
Dual<S> operator-(const Dual<S>& a, const Dual<S>& b) {
  return {a.v - b.v, a.d - b.d};
}
template <typename S>
Dual<S> operator-(const Dual<S>& a) {
  return {-a.v, -a.d};
}
template <typename S>
Dual<S> operator*(const Dual<S>& a, const Dual<S>& b) {
  return {a.v * b.v, a.d * b.v + a.v * b.d};
}
template <typename S>
Dual<S> operator*(double s, const Dual<S>& a) {
  return {s * a.v, s * a.d};
}
template <typename S>
Dual<S> operator*(const S& s, const Dual<S>& a) {
  return {s * a.v, s * a.d};
}
template <typename S>
Dual<S> operator/(const Dual<S>& a, double s) {
  return {a.v / s, a.d / s};
}
template <typename S>
Dual<S> operator/(const Dual<S>& a, const Dual<S>& b) {
  return {a.v / b.v, (a.d * b.v - a.v * b.d) / (b.v * b.v)};
}
template <typename S>
bool operator>(const Dual<S>& a, const Dual<S>& b) {
  return a.v > b.v;
}
template <typename S>
Dual<S> exp(const Dual<S>& a) {
  using std::exp;
  const S e = exp(a.v);
  return {e, e * a.d};
}
template <typename S>
Dual<S> log1p(const Dual<S>& a) {
  using std::log1p;
  return {log1p(a.v), a.d / (S(1.0) + a.v)};
}
template <typename S>
Dual<S> sin(const Dual<S>& a) {
  using std::cos;
  using std::sin;
  return {sin(a.v), cos(a.v) * a.d};
}
template <typename S>
Dual<S> cos(const Dual<S>& a) {
  using std::cos;
  using std::sin;
  return {cos(a.v), -sin(a.v) * a.d};
}

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
