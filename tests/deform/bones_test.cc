#include "banmo/deform/bones.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace banmo {
namespace {

struct Rig {
  int B;
  std::vector<double> bones, bones_t;
};

Rig RandomRig(int B, uint32_t seed, double motion) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Rig rig{B, std::vector<double>(kBoneSize * B), std::vector<double>(kPoseSize * B)};
  for (int b = 0; b < B; ++b) {
    double* bone = rig.bones.data() + kBoneSize * b;
    const Pose q =
        PoseFromAngleAxis(Eigen::Vector3d(u(rng), u(rng), u(rng)), Eigen::Vector3d::Zero());
    for (int k = 0; k < 3; ++k) bone[kBoneCenter + k] = 0.5 * u(rng);
    std::copy(q.data(), q.data() + 4, bone + kBoneQw);
    for (int k = 0; k < 3; ++k) bone[kBoneLogScale + k] = std::log(0.2) + 0.3 * u(rng);
    const Pose j = PoseFromAngleAxis(motion * Eigen::Vector3d(u(rng), u(rng), u(rng)),
                                     motion * Eigen::Vector3d(u(rng), u(rng), u(rng)));
    std::copy(j.data(), j.data() + kPoseSize, rig.bones_t.data() + kPoseSize * b);
  }
  return rig;
}

// The hand-written blend Jacobian of WarpWithJacobian against its autodiff
// twin: the templated warp with Jets over (x, all bones, all transforms).
TEST(WarpWithJacobian, EqualsAutodiffTwin) {
  for (WarpDirection dir : {WarpDirection::kBackward, WarpDirection::kForward}) {
    const Rig rig = RandomRig(3, 11, 0.4);
    constexpr int kDim = 3 + 3 * kBoneSize + 3 * kPoseSize;  // 54 directions
    using J = ceres::Jet<double, kDim>;
    const double x[3] = {0.2, -0.1, 0.3};
    J xj[3], bj[3 * kBoneSize], tj[3 * kPoseSize], out[3];
    for (int k = 0; k < 3; ++k) xj[k] = J(x[k], k);
    for (int k = 0; k < 3 * kBoneSize; ++k) bj[k] = J(rig.bones[k], 3 + k);
    for (int k = 0; k < 3 * kPoseSize; ++k) tj[k] = J(rig.bones_t[k], 3 + 3 * kBoneSize + k);
    if (dir == WarpDirection::kBackward) {
      BackwardWarp(3, bj, tj, xj, out);
    } else {
      ForwardWarp(3, bj, tj, xj, out);
    }
    double value[3];
    WarpJacobian jac;
    WarpWithJacobian(dir, 3, rig.bones.data(), rig.bones_t.data(), x, value, &jac);
    for (int r = 0; r < 3; ++r) {
      EXPECT_NEAR(value[r], out[r].a, 1e-14);
      // Exact derivatives both ways; 1e-12 absolute on O(1) entries.
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(jac.d_x(r, c), out[r].v[c], 1e-12);
      for (int c = 0; c < 3 * kBoneSize; ++c)
        EXPECT_NEAR(jac.d_bones(r, c), out[r].v[3 + c], 1e-12);
      for (int c = 0; c < 3 * kPoseSize; ++c) {
        EXPECT_NEAR(jac.d_bones_t(r, c), out[r].v[3 + 3 * kBoneSize + c], 1e-12);
      }
    }
  }
}

TEST(Warps, IdentityWithoutBonesOrWithIdentityTransforms) {
  const double x[3] = {0.3, 0.2, -0.4};
  double y[3];
  BackwardWarp<double>(0, nullptr, nullptr, x, y);
  EXPECT_EQ(y[0], x[0]);
  Rig rig = RandomRig(4, 3, 0.0);  // zero motion: identity transforms
  BackwardWarp(4, rig.bones.data(), rig.bones_t.data(), x, y);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(y[k], x[k], 1e-15);
  ForwardWarp(4, rig.bones.data(), rig.bones_t.data(), x, y);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(y[k], x[k], 1e-15);
}

TEST(Warps, RigidMotionOfAllBonesIsInvertedExactly) {
  // All bones move with the same transform: forward then backward is the
  // identity whatever the weights.
  Rig rig = RandomRig(5, 4, 0.0);
  const Pose j = PoseFromAngleAxis(Eigen::Vector3d(0.3, -0.2, 0.5), Eigen::Vector3d(0.1, 0.2, 0.0));
  for (int b = 0; b < 5; ++b)
    std::copy(j.data(), j.data() + kPoseSize, rig.bones_t.data() + kPoseSize * b);
  const double x[3] = {0.1, 0.4, -0.2};
  double posed[3], back[3];
  ForwardWarp(5, rig.bones.data(), rig.bones_t.data(), x, posed);
  BackwardWarp(5, rig.bones.data(), rig.bones_t.data(), posed, back);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], x[k], 1e-12);
}

TEST(Skinning, WeightsSumToOneForExtremeLogits) {
  const double logits[4] = {1e4, -1e8, 1e4 - 2.0, -3.0};
  double w[4];
  SkinningWeights(4, logits, w);
  double sum = 0;
  for (double v : w) {
    EXPECT_TRUE(std::isfinite(v));
    sum += v;
  }
  EXPECT_NEAR(sum, 1.0, 1e-15);
  EXPECT_NEAR(w[0], 1.0 / (1.0 + std::exp(-2.0)), 1e-12);
}

TEST(Skinning, LogitIsGaussianMahalanobis) {
  double bone[kBoneSize];
  InitializeBones({Eigen::Vector3d(1, 2, 3)}, 0.5, bone);
  const double y[3] = {1.5, 2, 3};  // 0.5 along x: d^2 / s^2 = 1
  EXPECT_NEAR(BoneLogit(bone, y), -0.5, 1e-14);
}

}  // namespace
}  // namespace banmo
