#include "banmo/geometry/se3.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "banmo/geometry/nearest_rotation.h"

namespace banmo {
namespace {

// Pure double arithmetic on O(1) values: 1e-12 leaves room for a few ulps.
constexpr double kTol = 1e-12;

Pose TestPose() {
  return PoseFromAngleAxis(Eigen::Vector3d(0.3, -0.7, 0.2), Eigen::Vector3d(0.5, -1.0, 2.0));
}

TEST(Se3, TransformMatchesEigenIsometry) {
  const Pose b_from_a = TestPose();
  const Eigen::Isometry3d iso = IsometryFromPose(b_from_a.data());
  const Eigen::Vector3d x_in_a(0.1, 0.2, -0.3);
  Eigen::Vector3d x_in_b;
  PoseTransformPoint(b_from_a.data(), x_in_a.data(), x_in_b.data());
  EXPECT_LT((x_in_b - iso * x_in_a).norm(), kTol);
  Eigen::Vector3d back;
  PoseInverseTransformPoint(b_from_a.data(), x_in_b.data(), back.data());
  EXPECT_LT((back - x_in_a).norm(), kTol);
}

TEST(Se3, ComposeAndInverse) {
  const Pose c_from_b = TestPose();
  const Pose b_from_a =
      PoseFromAngleAxis(Eigen::Vector3d(-1.0, 0.1, 0.4), Eigen::Vector3d(1, 2, 3));
  Pose c_from_a, a_from_b;
  PoseCompose(c_from_b.data(), b_from_a.data(), c_from_a.data());
  PoseInverse(b_from_a.data(), a_from_b.data());
  const Eigen::Vector3d x(0.4, -0.5, 0.6);
  Eigen::Vector3d y1, y2, y3, x_back;
  PoseTransformPoint(b_from_a.data(), x.data(), y1.data());
  PoseTransformPoint(c_from_b.data(), y1.data(), y2.data());
  PoseTransformPoint(c_from_a.data(), x.data(), y3.data());
  EXPECT_LT((y2 - y3).norm(), kTol);
  PoseTransformPoint(a_from_b.data(), y1.data(), x_back.data());
  EXPECT_LT((x_back - x).norm(), kTol);
  EXPECT_NEAR(RotationAngleBetween(c_from_a.data(), c_from_a.data()), 0.0, 1e-7);
}

TEST(Se3, UnnormalisedQuaternionIsTheSameRotation) {
  Pose p = TestPose();
  Pose scaled = p;
  scaled.head<4>() *= 3.0;
  const Eigen::Vector3d x(1, 2, 3);
  Eigen::Vector3d y1, y2;
  PoseTransformPoint(p.data(), x.data(), y1.data());
  PoseTransformPoint(scaled.data(), x.data(), y2.data());
  EXPECT_LT((y1 - y2).norm(), 1e-12);
}

TEST(Se3, WorksWithJets) {
  using J = ceres::Jet<double, 7>;
  const Pose p = TestPose();
  J pose[kPoseSize];
  for (int i = 0; i < kPoseSize; ++i) pose[i] = J(p[i], i);
  const J x[3] = {J(0.1), J(0.2), J(0.3)};
  J y[3];
  PoseTransformPoint(pose, x, y);
  // d y / d t = identity.
  EXPECT_NEAR(y[0].v[kPoseT + 0], 1.0, kTol);
  EXPECT_NEAR(y[1].v[kPoseT + 0], 0.0, kTol);
  EXPECT_TRUE(ceres::isfinite(y[2]));
}

TEST(NearestRotation, KeepsARotationAndRemovesScaleNoiseAndReflection) {
  const Eigen::Matrix3d r = IsometryFromPose(TestPose().data()).linear();
  EXPECT_LT((NearestRotation(r) - r).norm(), kTol);
  // A scaled rotation plus a small perturbation projects back near it.
  Eigen::Matrix3d noise;
  noise << 1e-3, -2e-3, 0, 0, 1e-3, 3e-3, -1e-3, 0, 2e-3;
  const Eigen::Matrix3d n = NearestRotation(2.5 * r + noise);
  EXPECT_NEAR(n.determinant(), 1.0, kTol);
  EXPECT_LT((n * n.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT((n - r).norm(), 2e-3);
  // A reflection's nearest rotation has determinant +1, not -1.
  const Eigen::Matrix3d reflection = Eigen::Vector3d(1, 1, -1).asDiagonal();
  EXPECT_NEAR(NearestRotation(r * reflection).determinant(), 1.0, kTol);
}

}  // namespace
}  // namespace banmo
