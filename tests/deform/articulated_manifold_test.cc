#include "banmo/deform/articulated_manifold.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "banmo/deform/bone_joints.h"
#include "banmo/deform/bones.h"
#include "banmo/geometry/se3.h"

namespace banmo {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Rest bones at the given centres, identity orientation, scale 0.1.
std::vector<double> Bones(const std::vector<Eigen::Vector3d>& centres) {
  std::vector<double> bones(kBoneSize * centres.size());
  for (size_t b = 0; b < centres.size(); ++b) {
    double* p = bones.data() + kBoneSize * b;
    for (int k = 0; k < 3; ++k) p[kBoneCenter + k] = centres[b][k];
    p[kBoneQw] = 1.0;
    for (int k = 0; k < 3; ++k) p[kBoneLogScale + k] = std::log(0.1);
  }
  return bones;
}

// A body of three bones along x (0, 1, 2) and a two-bone leg (3, 4) hanging
// from bone 1: the tree's centre is bone 1.
std::vector<double> BodyAndLeg() {
  return Bones({{-0.3, 0, 0}, {0, 0, 0}, {0.3, 0, 0}, {0, -0.3, 0}, {0, -0.6, 0}});
}

// Random poses with unit quaternions (rotations up to about 35 deg).
std::vector<double> RandomPoses(int count, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 0.3);
  std::vector<double> x(kPoseSize * count);
  for (int b = 0; b < count; ++b) {
    Eigen::Quaterniond q(1.0, n(*rng), n(*rng), n(*rng));
    q.normalize();
    double* p = x.data() + kPoseSize * b;
    p[0] = q.w();
    p[1] = q.x();
    p[2] = q.y();
    p[3] = q.z();
    for (int k = 0; k < 3; ++k) p[kPoseT + k] = n(*rng);
  }
  return x;
}

Eigen::Vector3d Apply(const double* pose, const Eigen::Vector3d& p) {
  Eigen::Vector3d out;
  PoseTransformPoint(pose, p.data(), out.data());
  return out;
}

// BodyAndLeg's bones, their tree and the manifold of five bones on it.
class ArticulatedBoneManifold : public testing::Test {
 protected:
  const std::vector<double> bones = BodyAndLeg();
  const BoneTree tree = MakeBoneTree(bones.data(), 5);
  const std::unique_ptr<ceres::Manifold> manifold = MakeArticulatedBoneManifold(5, &tree);
};

TEST(BoneTree, RootedAtTheCentreWithJointsAsPivots) {
  const std::vector<double> bones = BodyAndLeg();
  const BoneTree tree = MakeBoneTree(bones.data(), 5);
  EXPECT_EQ(tree.root, 1);
  ASSERT_EQ(tree.order.size(), 5u);
  EXPECT_EQ(tree.order[0], 1);
  const int expected_parent[5] = {1, -1, 1, 1, 3};
  for (int b = 0; b < 5; ++b) EXPECT_EQ(tree.parent[b], expected_parent[b]) << b;
  // Parents come before their children.
  std::vector<int> position(5);
  for (int i = 0; i < 5; ++i) position[tree.order[i]] = i;
  for (int b = 0; b < 5; ++b) {
    if (tree.parent[b] >= 0) {
      EXPECT_LT(position[tree.parent[b]], position[b]);
    }
  }
  // Equal widths: joints at the midpoints; the root pivots about its centre.
  EXPECT_LT((tree.pivot[1] - Eigen::Vector3d(0, 0, 0)).norm(), 1e-12);
  EXPECT_LT((tree.pivot[4] - Eigen::Vector3d(0, -0.45, 0)).norm(), 1e-12);
  EXPECT_LT((tree.pivot[0] - Eigen::Vector3d(-0.15, 0, 0)).norm(), 1e-12);
  EXPECT_EQ(tree.TangentSize(), 18);
  EXPECT_EQ(tree.tangent_offset[1], 0);
  EXPECT_EQ(tree.tangent_offset[0], 6);
  EXPECT_EQ(tree.tangent_offset[4], 15);
  EXPECT_EQ(MakeBoneTree(nullptr, 0).TangentSize(), 0);
}

TEST_F(ArticulatedBoneManifold, ZeroStepAndRootTranslation) {
  EXPECT_EQ(manifold->AmbientSize(), 35);
  EXPECT_EQ(manifold->TangentSize(), 18);
  std::mt19937 rng(3);
  const std::vector<double> x = RandomPoses(5, &rng);
  std::vector<double> delta(18, 0.0), y(35);
  ASSERT_TRUE(manifold->Plus(x.data(), delta.data(), y.data()));
  for (int i = 0; i < 35; ++i) EXPECT_NEAR(y[i], x[i], 1e-15) << i;
  // The root's v translates every bone.
  delta[3] = 0.1;
  delta[4] = -0.2;
  delta[5] = 0.05;
  ASSERT_TRUE(manifold->Plus(x.data(), delta.data(), y.data()));
  for (int b = 0; b < 5; ++b) {
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(y[7 * b + k], x[7 * b + k], 1e-15);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(y[7 * b + 4 + k], x[7 * b + 4 + k] + delta[3 + k], 1e-15);
  }
}

// A turn of the leg's upper bone (3): its joint with the body stays where
// bone 3 put it, the lower bone (4) turns with it rigidly, the body bones do
// not move.
TEST_F(ArticulatedBoneManifold, ABoneTurnsAboutItsJointAndCarriesItsSubtree) {
  std::mt19937 rng(5);
  const std::vector<double> x = RandomPoses(5, &rng);
  std::vector<double> delta(18, 0.0), y(35);
  delta[tree.tangent_offset[3] + 0] = 0.2;
  delta[tree.tangent_offset[3] + 2] = -0.1;
  ASSERT_TRUE(manifold->Plus(x.data(), delta.data(), y.data()));
  for (int b : {0, 1, 2}) {
    for (int k = 0; k < 7; ++k) EXPECT_NEAR(y[7 * b + k], x[7 * b + k], 1e-15);
  }
  const Eigen::Vector3d m = tree.pivot[3];
  EXPECT_LT((Apply(&y[21], m) - Apply(&x[21], m)).norm(), 1e-12);
  // Bone 4 relative to bone 3 is unchanged: J_3^-1 J_4 the same before and after.
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.1, -0.5, 0.2), Eigen::Vector3d(-0.3, 0, 1)}) {
    Eigen::Vector3d before, after;
    PoseInverseTransformPoint(&x[21], Apply(&x[28], p).data(), before.data());
    PoseInverseTransformPoint(&y[21], Apply(&y[28], p).data(), after.data());
    EXPECT_LT((before - after).norm(), 1e-12);
  }
  // And bone 3 did turn: by 2 |w| (Ceres' quaternion step).
  const Eigen::Quaterniond q0(x[21], x[22], x[23], x[24]), q1(y[21], y[22], y[23], y[24]);
  EXPECT_NEAR(q1.angularDistance(q0), 2.0 * std::hypot(0.2, 0.1), 1e-9);
}

// Every step moves whole subtrees rigidly, so each joint's gap
// |J_a m - J_b m| keeps its length, for any step from any poses.
TEST_F(ArticulatedBoneManifold, StepsKeepTheJointGaps) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 0.4);
  for (int trial = 0; trial < 5; ++trial) {
    const std::vector<double> x = RandomPoses(5, &rng);
    std::vector<double> delta(18), y(35);
    for (double& d : delta) d = n(rng);
    ASSERT_TRUE(manifold->Plus(x.data(), delta.data(), y.data()));
    for (const BoneJoint& j : FindBoneJoints(bones.data(), 5)) {
      const double before = (Apply(&x[7 * j.a], j.point) - Apply(&x[7 * j.b], j.point)).norm();
      const double after = (Apply(&y[7 * j.a], j.point) - Apply(&y[7 * j.b], j.point)).norm();
      EXPECT_GT(before, 1e-3);  // random poses: the joints are open
      EXPECT_NEAR(after, before, 1e-12) << "joint " << j.a << "-" << j.b;
    }
  }
}

// PlusJacobian (Jets) against central differences of Plus: step 1e-6,
// truncation error O(1e-12) and rounding O(1e-10) against entries of order 1.
TEST_F(ArticulatedBoneManifold, PlusJacobianAgreesWithNumericDifferentiation) {
  std::mt19937 rng(11);
  const std::vector<double> x = RandomPoses(5, &rng);
  RowMajorMatrix jac(35, 18);
  ASSERT_TRUE(manifold->PlusJacobian(x.data(), jac.data()));
  const double h = 1e-6;
  std::vector<double> delta(18, 0.0), plus(35), minus(35);
  for (int c = 0; c < 18; ++c) {
    delta[c] = h;
    ASSERT_TRUE(manifold->Plus(x.data(), delta.data(), plus.data()));
    delta[c] = -h;
    ASSERT_TRUE(manifold->Plus(x.data(), delta.data(), minus.data()));
    delta[c] = 0.0;
    for (int r = 0; r < 35; ++r) {
      EXPECT_NEAR(jac(r, c), (plus[r] - minus[r]) / (2 * h), 1e-8) << r << ", " << c;
    }
  }
  // Full column rank: no tangent direction is wasted.
  EXPECT_EQ(jac.colPivHouseholderQr().rank(), 18);
}

// Minus is first order: Minus(Plus(x, d), x) = d + O(|d|^2); with entries
// of d about 1e-4 the error is about 1e-7 (|d|^2 times the pseudo-inverse's
// norm and the curvature of the poses), so the bound is 1e-6, a hundredth of
// d: a zeroth-order or wrongly scaled Minus misses it by far.
TEST_F(ArticulatedBoneManifold, MinusUndoesASmallPlus) {
  std::mt19937 rng(13);
  std::normal_distribution<double> n(0.0, 1e-4);
  const std::vector<double> x = RandomPoses(5, &rng);
  std::vector<double> delta(18), y(35), back(18);
  for (double& d : delta) d = n(rng);
  ASSERT_TRUE(manifold->Plus(x.data(), delta.data(), y.data()));
  ASSERT_TRUE(manifold->Minus(y.data(), x.data(), back.data()));
  for (int i = 0; i < 18; ++i) EXPECT_NEAR(back[i], delta[i], 1e-6) << i;
  RowMajorMatrix plus(35, 18), minus(18, 35);
  ASSERT_TRUE(manifold->PlusJacobian(x.data(), plus.data()));
  ASSERT_TRUE(manifold->MinusJacobian(x.data(), minus.data()));
  EXPECT_LT((minus * plus - Eigen::MatrixXd::Identity(18, 18)).norm(), 1e-9);
}

// One bone: the root alone, a turn about its centre and a translation.
TEST_F(ArticulatedBoneManifold, OneBoneTurnsAboutItsCentre) {
  const std::vector<double> one_bone = Bones({{0.2, 0.1, 0}});
  const BoneTree one_tree = MakeBoneTree(one_bone.data(), 1);
  const auto one = MakeArticulatedBoneManifold(1, &one_tree);
  EXPECT_EQ(one->TangentSize(), 6);
  std::mt19937 rng(17);
  const std::vector<double> x = RandomPoses(1, &rng);
  const double delta[6] = {0.1, 0.2, -0.3, 0, 0, 0};
  double y[7];
  ASSERT_TRUE(one->Plus(x.data(), delta, y));
  const Eigen::Vector3d c(0.2, 0.1, 0);
  EXPECT_LT((Apply(y, c) - Apply(x.data(), c)).norm(), 1e-12);
}

}  // namespace
}  // namespace banmo
