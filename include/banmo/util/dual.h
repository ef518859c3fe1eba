// A forward-mode dual number x = value + eps * tangent (eps^2 = 0) over any
// scalar S (double or ceres::Jet). Used where a directional derivative must
// itself be differentiated with Jets, e.g. the SDF gradient inside the
// eikonal term's full-Jet reference: nested ceres::Jets do not mix with the
// double constants of templated code, this type converts from them
// implicitly like a Jet does from double.
#pragma once

#include <cmath>
#include <type_traits>

namespace banmo {

template <typename S>
struct Dual {
  S value;
  S tangent;
  Dual() : value(0.0), tangent(0.0) {}
  Dual(double x) : value(x), tangent(0.0) {}  // NOLINT(google-explicit-constructor)
  template <typename U = S, std::enable_if_t<!std::is_same_v<U, double>, int> = 0>
  Dual(const S& x) : value(x), tangent(0.0) {}  // NOLINT(google-explicit-constructor)
  Dual(const S& x, const S& dx) : value(x), tangent(dx) {}
  Dual& operator+=(const Dual& o) {
    value += o.value;
    tangent += o.tangent;
    return *this;
  }
  Dual& operator-=(const Dual& o) {
    value -= o.value;
    tangent -= o.tangent;
    return *this;
  }
  Dual& operator*=(const Dual& o) {
    tangent = tangent * o.value + value * o.tangent;
    value *= o.value;
    return *this;
  }
};

template <typename S>
Dual<S> operator+(const Dual<S>& a, const Dual<S>& b) {
  return {a.value + b.value, a.tangent + b.tangent};
}
template <typename S>
Dual<S> operator-(const Dual<S>& a, const Dual<S>& b) {
  return {a.value - b.value, a.tangent - b.tangent};
}
template <typename S>
Dual<S> operator-(const Dual<S>& a) {
  return {-a.value, -a.tangent};
}
template <typename S>
Dual<S> operator*(const Dual<S>& a, const Dual<S>& b) {
  return {a.value * b.value, a.tangent * b.value + a.value * b.tangent};
}
template <typename S>
Dual<S> operator*(double s, const Dual<S>& a) {
  return {s * a.value, s * a.tangent};
}
template <typename S, std::enable_if_t<!std::is_same_v<S, double>, int> = 0>
Dual<S> operator*(const S& s, const Dual<S>& a) {
  return {s * a.value, s * a.tangent};
}
template <typename S>
Dual<S> operator/(const Dual<S>& a, double s) {
  return {a.value / s, a.tangent / s};
}
template <typename S>
Dual<S> operator/(const Dual<S>& a, const Dual<S>& b) {
  return {a.value / b.value, (a.tangent * b.value - a.value * b.tangent) / (b.value * b.value)};
}
template <typename S>
bool operator>(const Dual<S>& a, const Dual<S>& b) {
  return a.value > b.value;
}
template <typename S>
bool operator<(const Dual<S>& a, const Dual<S>& b) {
  return a.value < b.value;
}
template <typename S>
bool operator<=(const Dual<S>& a, const Dual<S>& b) {
  return a.value <= b.value;
}
template <typename S>
Dual<S> exp(const Dual<S>& a) {
  using std::exp;
  const S e = exp(a.value);
  return {e, e * a.tangent};
}
template <typename S>
Dual<S> log1p(const Dual<S>& a) {
  using std::log1p;
  return {log1p(a.value), a.tangent / (S(1.0) + a.value)};
}
template <typename S>
Dual<S> sin(const Dual<S>& a) {
  using std::cos;
  using std::sin;
  return {sin(a.value), cos(a.value) * a.tangent};
}
template <typename S>
Dual<S> cos(const Dual<S>& a) {
  using std::cos;
  using std::sin;
  return {cos(a.value), -sin(a.value) * a.tangent};
}

}  // namespace banmo
