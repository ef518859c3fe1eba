#include "banmo/volume/volume_rendering.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

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
  CompositeWeights(32, sdf.data(), std::log(0.01), s.deltas.data(), DensityModel::kVolSdf,
                   tau.data());
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

// Both densities: finite weights and derivatives for tiny beta (an opaque
// step at the crossing), summing to the opacity 1. NeuS puts the whole
// opacity on the interval of the crossing, and the last sample has none.
TEST(CompositeWeights, TinyBetaGivesFiniteStepWeights) {
  using J = ceres::Jet<double, 1>;
  for (DensityModel density : {DensityModel::kVolSdf, DensityModel::kNeus}) {
    std::vector<J> sdf(16), tau(16);
    std::vector<double> deltas(16, 0.1);
    for (int i = 0; i < 16; ++i) sdf[i] = J(0.45 - 0.1 * i, 0);
    CompositeWeights(16, sdf.data(), J(std::log(1e-4)), deltas.data(), density, tau.data());
    double total = 0;
    for (const J& t : tau) {
      EXPECT_TRUE(ceres::isfinite(t)) << EnumName(density);
      total += t.a;
    }
    EXPECT_NEAR(total, 1.0, 1e-9) << EnumName(density);
    if (density == DensityModel::kNeus) {
      EXPECT_EQ(tau[4].a, 1.0);  // 0.05 -> -0.05
      EXPECT_EQ(tau[15].a, 0.0);
    }
  }
}

// Opacity of a ray passing at distance `miss` outside a sphere of radius R
// (negative: through it), with many samples so discretisation is small.
double SphereRayOpacity(DensityModel density, double radius, double miss, double beta) {
  const int n = 4000;
  const double half = 3.0;  // the ray runs from x = -3 to 3 at height R + miss
  std::vector<double> sdf(n), deltas(n, 2 * half / n), tau(n);
  for (int i = 0; i < n; ++i) {
    const double x = -half + (i + 0.5) * 2 * half / n;
    sdf[i] = std::hypot(x, radius + miss) - radius;
  }
  CompositeWeights(n, sdf.data(), std::log(beta), deltas.data(), density, tau.data());
  double opacity = 0;
  for (double t : tau) opacity += t;
  return opacity;
}

// NeuS: a ray grazing the zero level set has opacity 1/2 whatever the
// curvature, so the silhouette is the zero level set's; a ray whose SDF
// falls to m has opacity 1 - sigmoid(m / beta) (3 beta outside: 0.047). VolSDF's grazing
// opacity depends on the radius and exceeds 1/2 (its silhouette lies outside).
TEST(CompositeWeights, NeusGrazingRayHasHalfOpacityAtAnyCurvature) {
  const double beta = 0.05;
  for (double radius : {0.1, 0.3, 1.0}) {
    // 4,000 samples over 6 units: 0.0015 apart, so the sampled minimum of the
    // SDF is within ~1e-5 of the true one; 1e-3 on the opacity.
    EXPECT_NEAR(SphereRayOpacity(DensityModel::kNeus, radius, 0.0, beta), 0.5, 1e-3) << radius;
    EXPECT_NEAR(SphereRayOpacity(DensityModel::kNeus, radius, 3 * beta, beta),
                1.0 / (1.0 + std::exp(3.0)), 1e-3)
        << radius;
    // Through the sphere, reaching depth R / 2 inside: 1 - sigmoid(-R / (2 beta))
    // (the start, f_0 >= 2, has Phi = 1 to 1e-17).
    EXPECT_NEAR(SphereRayOpacity(DensityModel::kNeus, radius, -0.5 * radius, beta),
                1.0 - 1.0 / (1.0 + std::exp(0.5 * radius / beta)), 1e-3)
        << radius;
    EXPECT_GT(SphereRayOpacity(DensityModel::kVolSdf, radius, 0.0, beta), 0.6) << radius;
  }
}

// NeuS weights' Jets against central differences in every SDF value and
// log beta, on a ray that enters and leaves a soft object (rising SDF
// intervals get no opacity: their kink is away from these values).
TEST(CompositeWeights, NeusJetsMatchCentralDifferences) {
  constexpr int kN = 8;
  using J = ceres::Jet<double, kN + 1>;
  const double f[kN] = {0.4, 0.22, 0.07, -0.06, -0.11, -0.02, 0.13, 0.31};
  const double log_beta = std::log(0.08);
  std::vector<J> sdf(kN), tau(kN);
  for (int i = 0; i < kN; ++i) sdf[i] = J(f[i], i);
  std::vector<double> deltas(kN, 0.1);
  CompositeWeights(kN, sdf.data(), J(log_beta, kN), deltas.data(), DensityModel::kNeus, tau.data());
  auto weights = [&](const double* values, double lb) {
    std::vector<double> out(kN);
    CompositeWeights(kN, values, lb, deltas.data(), DensityModel::kNeus, out.data());
    return out;
  };
  // Step 1e-6: truncation error ~1e-12 x third derivative (O(1 / beta^3) ~
  // 2e3), rounding ~1e-16 / 1e-6; 1e-7 leaves room for both.
  const double h = 1e-6;
  for (int k = 0; k <= kN; ++k) {
    double plus[kN], minus[kN];
    std::copy(f, f + kN, plus);
    std::copy(f, f + kN, minus);
    double lb_plus = log_beta, lb_minus = log_beta;
    if (k < kN) {
      plus[k] += h;
      minus[k] -= h;
    } else {
      lb_plus += h;
      lb_minus -= h;
    }
    const std::vector<double> a = weights(plus, lb_plus), b = weights(minus, lb_minus);
    for (int i = 0; i < kN; ++i) {
      EXPECT_NEAR(tau[i].v[k], (a[i] - b[i]) / (2 * h), 1e-7) << "tau " << i << " d " << k;
    }
  }
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
