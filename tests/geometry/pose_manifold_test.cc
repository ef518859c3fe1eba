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
// numeric differentiation) for the stacked manifolds.
TEST(StackedPoseManifold, SatisfiesCeresManifoldInvariants) {
  using namespace ceres;  // NOLINT: the invariant macros name Ceres' helpers unqualified
  const auto m = MakeStackedPoseManifold(3);
  EXPECT_EQ(m->AmbientSize(), 21);
  EXPECT_EQ(m->TangentSize(), 18);
  for (uint32_t seed = 0; seed < 5; ++seed) {
    const Eigen::VectorXd x = RandomPoses(3, 7, 0, seed);
    const Eigen::VectorXd delta = 0.1 * RandomPoses(3, 6, 0, seed + 10).head(18);
    const Eigen::VectorXd y = RandomPoses(3, 7, 0, seed + 20);
    const ceres::Manifold& manifold = *m;
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-9);
  }
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

}  // namespace
}  // namespace banmo
