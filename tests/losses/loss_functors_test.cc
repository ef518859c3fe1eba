// The loss functors on their own: zero at a constructed solution, the
// hand-computed value at a perturbed input.
#include <gtest/gtest.h>

#include "banmo/losses/cycle_2d_loss.h"
#include "banmo/losses/cycle_3d_loss.h"
#include "banmo/losses/feature_match_loss.h"
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

}  // namespace
}  // namespace banmo
