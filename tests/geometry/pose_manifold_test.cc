#include "banmo/geometry/pose_manifold.h"

#include <ceres/manifold_test_utils.h>
#include <gtest/gtest.h>

#include <random>

#include "banmo/geometry/se3.h"

namespace banmo {
namespace {

Eigen::VectorXd RandomPoses(int count, int stride, int q_offset, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::VectorXd x(count * stride);
  for (int i = 0; i < x.size(); ++i) x[i] = n(rng);
  for (int i = 0; i < count; ++i) x.segment<4>(stride * i + q_offset).normalize();
  return x;
}

// Ceres' own manifold invariants (Plus/Minus consistency, Jacobians against
// numeric differentiation) of a manifold of 3 stacked poses, at random
// poses and steps.
void ExpectThreePoseInvariants(const ceres::Manifold& manifold) {
  using namespace ceres;  // NOLINT: the invariant macros name Ceres' helpers unqualified
  EXPECT_EQ(manifold.AmbientSize(), 21);
  EXPECT_EQ(manifold.TangentSize(), 18);
  for (uint32_t seed = 0; seed < 5; ++seed) {
    const Eigen::VectorXd x = RandomPoses(3, 7, 0, seed);
    const Eigen::VectorXd delta = 0.1 * RandomPoses(3, 6, 0, seed + 10).head(18);
    const Eigen::VectorXd y = RandomPoses(3, 7, 0, seed + 20);
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-9);
  }
}

TEST(StackedPoseManifold, SatisfiesCeresManifoldInvariants) {
  ExpectThreePoseInvariants(*MakeStackedPoseManifold(3));
}

TEST(StackedQuaternionBlockManifold, SatisfiesCeresManifoldInvariants) {
  using namespace ceres;  // NOLINT
  const auto m = MakeStackedQuaternionBlockManifold(2, 10, 3);
  EXPECT_EQ(m->TangentSize(), 18);
  for (uint32_t seed = 0; seed < 5; ++seed) {
    const Eigen::VectorXd x = RandomPoses(2, 10, 3, seed);
    Eigen::VectorXd delta = 0.1 * Eigen::VectorXd::Random(18);
    const Eigen::VectorXd y = RandomPoses(2, 10, 3, seed + 20);
    const ceres::Manifold& manifold = *m;
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-9);
  }
}

TEST(PoseManifold, PlusMovesRotationAndTranslation) {
  const auto m = MakePoseManifold();
  const Pose x = PoseIdentity();
  const double delta[6] = {0.0, 0.0, 0.1, 1.0, 2.0, 3.0};
  Pose y;
  ASSERT_TRUE(m->Plus(x.data(), delta, y.data()));
  // Ceres' QuaternionManifold: a tangent step d rotates by the angle 2 |d|.
  EXPECT_NEAR(RotationAngleBetween(x.data(), y.data()), 0.2, 1e-12);
  EXPECT_NEAR(y[6], 3.0, 1e-15);
}

TEST(StackedPivotPoseManifold, SatisfiesCeresManifoldInvariants) {
  // Pivots in a block of stride 10 at offset 0, as the rest bone centres.
  const Eigen::VectorXd pivots = RandomPoses(3, 10, 3, 99);
  ExpectThreePoseInvariants(*MakeStackedPivotPoseManifold(3, pivots.data(), 10, 0));
}

// A rotation step turns the pose about its posed pivot R c + t, which stays
// where it is; the same rotation step of the origin-centred manifold moves
// it. The rotation part is the same in both, and with no rotation both
// move the translation alike.
TEST(StackedPivotPoseManifold, TurnsAboutThePosedPivot) {
  const Eigen::Vector3d pivot(0.7, -0.3, 0.2);
  const auto m = MakeStackedPivotPoseManifold(1, pivot.data(), 3, 0);
  const auto origin = MakeStackedPoseManifold(1);
  const Eigen::VectorXd x = RandomPoses(1, 7, 0, 3);
  const double turn[6] = {0.1, -0.2, 0.15, 0.0, 0.0, 0.0};
  Pose y, y_origin;
  ASSERT_TRUE(m->Plus(x.data(), turn, y.data()));
  ASSERT_TRUE(origin->Plus(x.data(), turn, y_origin.data()));
  EXPECT_LT((y.head<4>() - y_origin.head<4>()).norm(), 1e-15);
  Eigen::Vector3d before, after, after_origin;
  PoseTransformPoint(x.data(), pivot.data(), before.data());
  PoseTransformPoint(y.data(), pivot.data(), after.data());
  PoseTransformPoint(y_origin.data(), pivot.data(), after_origin.data());
  EXPECT_LT((after - before).norm(), 1e-14);
  EXPECT_GT((after_origin - before).norm(), 0.1);
  const double shift[6] = {0.0, 0.0, 0.0, 0.5, -1.0, 2.0};
  ASSERT_TRUE(m->Plus(x.data(), shift, y.data()));
  ASSERT_TRUE(origin->Plus(x.data(), shift, y_origin.data()));
  EXPECT_LT((y - y_origin).norm(), 1e-15);
  // The pivot is read at each call: a moved pivot is turned about.
  Eigen::Vector3d moved_pivot = pivot;
  const auto live = MakeStackedPivotPoseManifold(1, moved_pivot.data(), 3, 0);
  moved_pivot = Eigen::Vector3d(-1.0, 0.5, 0.25);
  ASSERT_TRUE(live->Plus(x.data(), turn, y.data()));
  PoseTransformPoint(x.data(), moved_pivot.data(), before.data());
  PoseTransformPoint(y.data(), moved_pivot.data(), after.data());
  EXPECT_LT((after - before).norm(), 1e-14);
}

}  // namespace
}  // namespace banmo
