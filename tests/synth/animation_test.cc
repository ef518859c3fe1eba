// glTF animation samplers on hand-made channels with known answers.
#include "banmo/synth/animation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

namespace banmo::synth {
namespace {

AnimationChannel ScalarChannel(Interpolation interp, std::vector<double> times,
                               std::vector<double> values) {
  AnimationChannel c;
  c.node = 0;
  c.path = ChannelPath::kWeights;  // any component count
  c.interpolation = interp;
  c.times = std::move(times);
  c.values = Eigen::Map<Eigen::MatrixXd>(values.data(), 1, values.size());
  return c;
}

TEST(SampleChannel, LinearInterpolatesAndClamps) {
  const auto c = ScalarChannel(Interpolation::kLinear, {1, 2, 4}, {10, 20, 0});
  ASSERT_EQ(c.Validate(), "");
  EXPECT_DOUBLE_EQ(SampleChannel(c, 0.0)[0], 10);  // before the first key: held
  EXPECT_DOUBLE_EQ(SampleChannel(c, 1.0)[0], 10);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 1.25)[0], 12.5);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 2.0)[0], 20);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 3.0)[0], 10);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 9.0)[0], 0);  // after the last key: held
}

TEST(SampleChannel, StepHoldsThePreviousKey) {
  const auto c = ScalarChannel(Interpolation::kStep, {0, 1, 2}, {5, 7, 9});
  EXPECT_DOUBLE_EQ(SampleChannel(c, 0.0)[0], 5);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 0.999)[0], 5);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 1.0)[0], 7);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 1.5)[0], 7);
  EXPECT_DOUBLE_EQ(SampleChannel(c, 2.5)[0], 9);
}

TEST(SampleChannel, CubicSplineReproducesACubic) {
  // p(t) = t^3 - 2 t on keys {0, 0.5, 2}: Hermite interpolation with exact
  // derivatives as tangents reproduces any cubic exactly (up to rounding).
  auto p = [](double t) { return t * t * t - 2 * t; };
  auto dp = [](double t) { return 3 * t * t - 2; };
  const std::vector<double> times = {0, 0.5, 2};
  std::vector<double> values;
  for (double t : times) {
    values.push_back(dp(t));  // in-tangent
    values.push_back(p(t));   // value
    values.push_back(dp(t));  // out-tangent
  }
  const auto c = ScalarChannel(Interpolation::kCubicSpline, times, values);
  ASSERT_EQ(c.Validate(), "");
  for (double t = 0; t <= 2; t += 0.05) {
    EXPECT_NEAR(SampleChannel(c, t)[0], p(t), 1e-12) << "t = " << t;
  }
}

TEST(SampleChannel, CubicSplineUsesInAndOutTangentsSeparately) {
  // One interval [0, 2], v0 = 0, out-tangent b0 = 1, v1 = 0, in-tangent a1 = 3.
  // At s = 0.5: (s^3 - 2 s^2 + s) dt b0 + (s^3 - s^2) dt a1
  //           = 0.125 * 2 * 1 + (-0.125) * 2 * 3 = -0.5.
  const auto c = ScalarChannel(Interpolation::kCubicSpline, {0, 2}, {-100, 0, 1, 3, 0, 100});
  EXPECT_NEAR(SampleChannel(c, 1.0)[0], -0.5, 1e-15);
}

TEST(SampleChannel, LinearRotationIsSlerpOnTheShortestArc) {
  AnimationChannel c;
  c.node = 0;
  c.path = ChannelPath::kRotation;
  c.interpolation = Interpolation::kLinear;
  c.times = {0, 1};
  const Eigen::Quaterniond q0(Eigen::AngleAxisd(0.0, Eigen::Vector3d::UnitZ()));
  // 120 degrees about z, stored with a negative w (the same rotation as +q):
  // slerp must still take the 120-degree arc, not the 240-degree one.
  Eigen::Quaterniond q1(Eigen::AngleAxisd(2 * M_PI / 3, Eigen::Vector3d::UnitZ()));
  q1.coeffs() *= -1;
  c.values.resize(4, 2);
  c.values.col(0) << q0.x(), q0.y(), q0.z(), q0.w();
  c.values.col(1) << q1.x(), q1.y(), q1.z(), q1.w();
  ASSERT_EQ(c.Validate(), "");
  const Eigen::VectorXd v = SampleChannel(c, 0.25);
  const Eigen::Quaterniond q(v[3], v[0], v[1], v[2]);
  const Eigen::AngleAxisd aa(q);
  // A quarter of 120 degrees = 30 degrees about +z, unit length (1e-12: rounding).
  EXPECT_NEAR(std::abs(aa.angle()), M_PI / 6, 1e-12);
  EXPECT_NEAR(std::abs(aa.axis().z()), 1.0, 1e-12);
  EXPECT_NEAR(q.norm(), 1.0, 1e-12);
}

TEST(SampleChannel, CubicSplineRotationIsNormalised) {
  AnimationChannel c;
  c.node = 0;
  c.path = ChannelPath::kRotation;
  c.interpolation = Interpolation::kCubicSpline;
  c.times = {0, 1};
  c.values = Eigen::MatrixXd::Zero(4, 6);
  c.values.col(1) << 0, 0, 0, 1;                          // identity
  c.values.col(4) << 0, 0, std::sin(0.5), std::cos(0.5);  // 1 rad about z
  const Eigen::VectorXd v = SampleChannel(c, 0.5);
  EXPECT_NEAR(v.norm(), 1.0, 1e-12);
  // Zero tangents: the midpoint of the Hermite blend of the two quaternions,
  // normalised, is the half-way rotation (0.5 rad) about z.
  EXPECT_NEAR(2 * std::atan2(v[2], v[3]), 0.5, 1e-12);
}

TEST(AnimationChannel, ValidateRejectsBadChannels) {
  EXPECT_NE(ScalarChannel(Interpolation::kLinear, {0, 0}, {1, 2}).Validate(), "");
  EXPECT_NE(ScalarChannel(Interpolation::kLinear, {0, 1}, {1}).Validate(), "");
  EXPECT_NE(ScalarChannel(Interpolation::kCubicSpline, {0, 1}, {1, 2}).Validate(), "");
  EXPECT_NE(ScalarChannel(Interpolation::kLinear, {0, NAN}, {1, 2}).Validate(), "");
}

TEST(Animation, WrapTimeLoops) {
  Animation a;
  a.channels.push_back(ScalarChannel(Interpolation::kLinear, {1, 3}, {0, 1}));
  EXPECT_DOUBLE_EQ(a.Duration(), 2);
  EXPECT_DOUBLE_EQ(a.WrapTime(1.5), 1.5);
  EXPECT_DOUBLE_EQ(a.WrapTime(3.5), 1.5);
  EXPECT_DOUBLE_EQ(a.WrapTime(0.5), 2.5);
}

}  // namespace
}  // namespace banmo::synth
