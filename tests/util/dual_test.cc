#include "banmo/util/dual.h"

#include <gtest/gtest.h>

#include <cmath>

namespace banmo {
namespace {

// The tangent of f(x + eps) is f'(x): compared with the analytic derivative
// (exact formulas, so only rounding separates them).
TEST(Dual, TangentsAreTheDerivatives) {
  const double x = 0.7;
  const Dual<double> d(x, 1.0);
  const Dual<double> y = exp(d) * sin(d) / (Dual<double>(2.0) + cos(d)) - log1p(d * d);
  const double value = std::exp(x) * std::sin(x) / (2.0 + std::cos(x)) - std::log1p(x * x);
  const double u = std::exp(x) * std::sin(x), du = std::exp(x) * (std::sin(x) + std::cos(x));
  const double v = 2.0 + std::cos(x), dv = -std::sin(x);
  const double derivative = (du * v - u * dv) / (v * v) - 2.0 * x / (1.0 + x * x);
  EXPECT_NEAR(y.value, value, 1e-15);
  EXPECT_NEAR(y.tangent, derivative, 1e-14);
}

TEST(Dual, CompoundAssignmentAndComparisons) {
  Dual<double> a(2.0, 1.0);
  a *= Dual<double>(3.0, 0.5);  // d(2 * 3) = 1 * 3 + 2 * 0.5
  EXPECT_EQ(a.value, 6.0);
  EXPECT_EQ(a.tangent, 4.0);
  a += 1.0;
  a -= Dual<double>(0.0, 1.0);
  EXPECT_EQ(a.value, 7.0);
  EXPECT_EQ(a.tangent, 3.0);
  EXPECT_TRUE(Dual<double>(1.0) < a);
  EXPECT_TRUE(a > Dual<double>(1.0));
  EXPECT_TRUE(Dual<double>(7.0, -5.0) <= a);  // compares values only
  const Dual<double> n = -(0.5 * a);
  EXPECT_EQ(n.value, -3.5);
  EXPECT_EQ(n.tangent, -1.5);
}

}  // namespace
}  // namespace banmo
