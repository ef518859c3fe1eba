// The loss functors on their own: zero at a constructed solution, the
// hand-computed value at a perturbed input.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>

#include "banmo/losses/cycle_2d_loss.h"
#include "banmo/losses/cycle_3d_loss.h"
#include "banmo/losses/feature_match_loss.h"
#include "banmo/losses/feature_render_loss.h"
#include "banmo/losses/flow_loss.h"
#include "banmo/losses/rgb_loss.h"
#include "banmo/losses/silhouette_loss.h"

namespace banmo {
namespace {

constexpr double kTol = 1e-14;  // a few ulps of O(1) values

TEST(RgbLoss, ZeroAtObservationAndWeighted) {
  const RgbLoss loss(Eigen::Vector3d(0.2, 0.4, 0.6), 4.0);
  double c[3] = {0.2, 0.4, 0.6}, r[3];
  loss(c, r);
  for (double v : r) EXPECT_NEAR(v, 0.0, kTol);
  c[1] = 0.5;
  loss(c, r);
  EXPECT_NEAR(r[1], 2.0 * 0.1, kTol);
}

TEST(SilhouetteLoss, OpacityMinusMask) {
  const SilhouetteLoss loss(1.0, 1.0);
  double o = 1.0, r;
  loss(&o, &r);
  EXPECT_NEAR(r, 0.0, kTol);
  o = 0.25;
  loss(&o, &r);
  EXPECT_NEAR(r, -0.75, kTol);
}

TEST(FlowLoss, DisplacementMinusObservedFlow) {
  const FlowLoss loss(Eigen::Vector2d(3.0, -1.0), 0.25);
  double d[2] = {3.0, -1.0}, r[2];
  loss(d, r);
  EXPECT_NEAR(r[0], 0.0, kTol);
  d[0] = 1003.0;  // large flows stay linear and finite
  loss(d, r);
  EXPECT_NEAR(r[0], 0.5 * 1000.0, 1e-10);
}

TEST(FeatureMatchLoss, MatchedMinusExpected) {
  const FeatureMatchLoss loss(1.0);
  const double a[3] = {0.1, 0.2, 0.3}, b[3] = {0.1, 0.0, 0.3};
  double r[3];
  loss(a, a, r);
  for (double v : r) EXPECT_NEAR(v, 0.0, kTol);
  loss(a, b, r);
  EXPECT_NEAR(r[1], 0.2, kTol);
}

TEST(FeatureRenderLoss, NormalisedRenderingMinusFeature) {
  Eigen::Matrix<double, 16, 1> f = Eigen::Matrix<double, 16, 1>::Zero();
  f[0] = 0.6;
  f[1] = 0.8;
  const FeatureRenderLoss loss(f, 4.0);
  double e[16] = {}, r[16];
  // Any positive multiple of the feature renders it exactly: the term
  // compares directions (the feature match's cosine similarity, Eq. 15).
  e[0] = 0.3;
  e[1] = 0.4;
  loss(e, r);
  for (double v : r) EXPECT_NEAR(v, 0.0, 1e-10);  // |e| floored at 1e-6: relative 2e-12
  // A rendering along the third axis: r = 2 (e_3 - f).
  e[0] = e[1] = 0.0;
  e[2] = 5.0;
  loss(e, r);
  EXPECT_NEAR(r[0], -1.2, 1e-12);
  EXPECT_NEAR(r[1], -1.6, 1e-12);
  EXPECT_NEAR(r[2], 2.0, 1e-12);
}

TEST(FeatureRenderLoss, FiniteAtAZeroRendering) {
  Eigen::Matrix<double, 16, 1> f = Eigen::Matrix<double, 16, 1>::Zero();
  f[3] = 1.0;
  const FeatureRenderLoss loss(f, 1.0);
  using J = ceres::Jet<double, 16>;
  J e[16], r[16];
  for (int k = 0; k < 16; ++k) e[k] = J(0.0, k);
  loss(e, r);
  for (int k = 0; k < 16; ++k) {
    EXPECT_NEAR(r[k].a, k == 3 ? -1.0 : 0.0, kTol);
    // d r / d e = I / floor at e = 0: large but finite.
    EXPECT_TRUE(std::isfinite(r[k].v.norm()));
    EXPECT_NEAR(r[k].v[k], 1.0 / FeatureRenderLoss::kNormFloor, 1.0);
  }
}

TEST(Cycle2dLoss, ProjectionMinusPixel) {
  const Cycle2dLoss loss(Eigen::Vector2d(10.5, 20.5), 1.0);
  double p[2] = {10.5, 20.5}, r[2];
  loss(p, r);
  EXPECT_NEAR(r[0], 0.0, kTol);
  p[1] = 22.5;
  loss(p, r);
  EXPECT_NEAR(r[1], 2.0, kTol);
}

TEST(Cycle3dLoss, WeightedByTau) {
  const Cycle3dLoss loss(0.25, 4.0);  // sqrt(4 * 0.25) = 1
  const double a[3] = {1, 2, 3}, b[3] = {1, 2, 2.5};
  double r[3];
  loss(a, a, r);
  for (double v : r) EXPECT_NEAR(v, 0.0, kTol);
  loss(a, b, r);
  EXPECT_NEAR(r[2], 0.5, kTol);
}

// Weights below kMinWarpTau count as 0 (the pipeline skips those samples'
// forward warps); at kMinWarpTau the term is the plain sqrt(w tau) one.
TEST(Cycle3dLoss, WeightsBelowMinWarpTauCountAsZero) {
  const double a[3] = {1, 2, 3}, b[3] = {1, 2, 2.5};
  double r[3];
  const Cycle3dLoss below(0.99 * kMinWarpTau, 4.0);
  EXPECT_FALSE(below.active());
  below(a, b, r);
  for (double v : r) EXPECT_EQ(v, 0.0);
  const Cycle3dLoss at(kMinWarpTau, 4.0);
  EXPECT_TRUE(at.active());
  at(a, b, r);
  EXPECT_NEAR(r[2], std::sqrt(4.0 * kMinWarpTau) * 0.5, kTol);
  EXPECT_FALSE(Cycle3dLoss(0.5, 0.0).active());  // no weight
}

}  // namespace
}  // namespace banmo
