#include "banmo/volume/volume_rendering.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace banmo {
namespace {

TEST(LaplaceDensity, ValuesAndContinuityAtTheSurface) {
  const double beta = 0.1, log_beta = std::log(beta);
  EXPECT_NEAR(LaplaceDensity(0.0, log_beta), 0.5 / beta, 1e-12);
  // Deep inside: 1/beta; far outside: 0.
  EXPECT_NEAR(LaplaceDensity(-10.0, log_beta), 1.0 / beta, 1e-12);
  EXPECT_NEAR(LaplaceDensity(10.0, log_beta), 0.0, 1e-12);
  // Continuous derivative across s = 0 (both branches: 0.5 / beta^2).
  using J = ceres::Jet<double, 1>;
  const J left = LaplaceDensity(J(-1e-12, 0), J(log_beta));
  const J right = LaplaceDensity(J(1e-12, 0), J(log_beta));
  EXPECT_NEAR(left.v[0], right.v[0], 1e-6);
  EXPECT_NEAR(left.v[0], -0.5 / (beta * beta), 1e-6);
}

TEST(LaplaceDensity, FiniteForExtremeBeta) {
  using J = ceres::Jet<double, 2>;
  for (double beta : {1e-4, 1e-8, 1e3}) {
    for (double s : {-5.0, -1e-6, 0.0, 1e-6, 5.0}) {
      const J d = LaplaceDensity(J(s, 0), J(std::log(beta), 1));
      EXPECT_TRUE(ceres::isfinite(d)) << beta << " " << s;
    }
  }
}

TEST(CompositeWeights, SumToOpacityBelowOne) {
  std::mt19937 rng(1);
  const RaySamples s = StratifiedSamples(32, 2.0, 4.0, 1.0, true, &rng);
  std::vector<double> sdf(32), tau(32);
  for (int i = 0; i < 32; ++i) sdf[i] = std::abs(s.depths[i] - 3.0) - 0.5;  // slab [2.5, 3.5]
  CompositeWeights(32, sdf.data(), std::log(0.01), s.deltas.data(), tau.data());
  double opacity = 0.0;
  for (double t : tau) {
    EXPECT_GE(t, 0.0);
    opacity += t;
  }
  EXPECT_LE(opacity, 1.0 + 1e-12);
  EXPECT_GT(opacity, 0.999);  // a thick, dense slab is opaque
  // The weight peaks at the first surface crossing (depth 2.5).
  const int peak = std::max_element(tau.begin(), tau.end()) - tau.begin();
  EXPECT_NEAR(s.depths[peak], 2.5, 2.0 / 32 + 1e-9);
}

TEST(CompositeWeights, TinyBetaGivesFiniteStepWeights) {
  using J = ceres::Jet<double, 1>;
  std::vector<J> sdf(16), tau(16);
  std::vector<double> deltas(16, 0.1);
  for (int i = 0; i < 16; ++i) sdf[i] = J(0.45 - 0.1 * i, 0);
  CompositeWeights(16, sdf.data(), J(std::log(1e-4)), deltas.data(), tau.data());
  double total = 0;
  for (const J& t : tau) {
    EXPECT_TRUE(ceres::isfinite(t));
    total += t.a;
  }
  EXPECT_NEAR(total, 1.0, 1e-9);
}

TEST(StratifiedSamples, OnePerBinAndPositiveDeltas) {
  std::mt19937 rng(3);
  const RaySamples s = StratifiedSamples(8, 1.0, 3.0, 1.5, true, &rng);
  for (int i = 0; i < 8; ++i) {
    EXPECT_GE(s.depths[i], 1.0 + 0.25 * i);
    EXPECT_LE(s.depths[i], 1.0 + 0.25 * (i + 1));
    EXPECT_GT(s.deltas[i], 0.0);
  }
  const RaySamples c = StratifiedSamples(4, 0.0, 4.0, 1.0, false, nullptr);
  EXPECT_DOUBLE_EQ(c.depths[0], 0.5);
  EXPECT_DOUBLE_EQ(c.deltas[3], 0.5);
}

}  // namespace
}  // namespace banmo
