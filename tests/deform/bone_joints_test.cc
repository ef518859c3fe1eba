#include "banmo/deform/bone_joints.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "banmo/deform/bones.h"

namespace banmo {
namespace {

// Rest bones at the given centres, identity orientation, scales s (per axis).
std::vector<double> Bones(const std::vector<Eigen::Vector3d>& centres,
                          const std::vector<Eigen::Vector3d>& scales) {
  std::vector<double> bones(kBoneSize * centres.size());
  for (size_t b = 0; b < centres.size(); ++b) {
    double* p = bones.data() + kBoneSize * b;
    for (int k = 0; k < 3; ++k) p[kBoneCenter + k] = centres[b][k];
    p[kBoneQw] = 1.0;
    for (int k = 0; k < 3; ++k) p[kBoneLogScale + k] = std::log(scales[b][k]);
  }
  return bones;
}

TEST(BoneJoints, NoneBelowTwoBones) {
  EXPECT_TRUE(FindBoneJoints(nullptr, 0).empty());
  const std::vector<double> one = Bones({Eigen::Vector3d::Zero()}, {Eigen::Vector3d::Ones()});
  EXPECT_TRUE(FindBoneJoints(one.data(), 1).empty());
}

TEST(BoneJoints, SpanningTreeOfALimbOnABody) {
  // A body of two bones along x and a two-bone leg hanging from bone 1:
  // the tree joins each bone to its nearest, not the foot to the body.
  const Eigen::Vector3d s(0.1, 0.1, 0.1);
  const std::vector<double> bones =
      Bones({{0, 0, 0}, {0.3, 0, 0}, {0.3, -0.3, 0}, {0.3, -0.6, 0}}, {s, s, s, s});
  const std::vector<BoneJoint> joints = FindBoneJoints(bones.data(), 4);
  ASSERT_EQ(joints.size(), 3u);
  const int expected[3][2] = {{0, 1}, {1, 2}, {2, 3}};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(joints[k].a, expected[k][0]);
    EXPECT_EQ(joints[k].b, expected[k][1]);
  }
  // Equal widths: the joint is the midpoint.
  EXPECT_LT((joints[1].point - Eigen::Vector3d(0.3, -0.15, 0)).norm(), 1e-12);
}

TEST(BoneJoints, PointSplitsTheSegmentByTheWidthsAlongIt) {
  // Bone 0 three times as wide along x as bone 1: the point where the two
  // Gaussians' logits are equal lies at 3/4 of the way from 0 to 1. The
  // widths across the segment do not matter.
  const std::vector<double> bones =
      Bones({{0, 0, 0}, {0.4, 0, 0}}, {{0.3, 0.05, 0.05}, {0.1, 0.2, 0.2}});
  const std::vector<BoneJoint> joints = FindBoneJoints(bones.data(), 2);
  ASSERT_EQ(joints.size(), 1u);
  EXPECT_LT((joints[0].point - Eigen::Vector3d(0.3, 0, 0)).norm(), 1e-12);
  // The logits agree there.
  const double la = BoneLogit(bones.data(), joints[0].point.data());
  const double lb = BoneLogit(bones.data() + kBoneSize, joints[0].point.data());
  EXPECT_NEAR(la, lb, 1e-12);
}

TEST(BoneJoints, DistanceCountsInWidths) {
  // Bone 2 is nearer to bone 0 than bone 1 is in metres, but bone 1 is wide
  // along the line to bone 0: in widths bone 1 is the nearer, and the tree's
  // first edge from bone 0 goes to it.
  const std::vector<double> bones = Bones({{0, 0, 0}, {0.5, 0, 0}, {0, 0.4, 0}},
                                          {{0.1, 0.1, 0.1}, {0.5, 0.1, 0.1}, {0.1, 0.1, 0.1}});
  const std::vector<BoneJoint> joints = FindBoneJoints(bones.data(), 3);
  ASSERT_EQ(joints.size(), 2u);
  EXPECT_EQ(joints[0].a, 0);
  EXPECT_EQ(joints[0].b, 1);  // 0.5 / 0.6 = 0.83 widths against 0.4 / 0.2 = 2
}

}  // namespace
}  // namespace banmo
