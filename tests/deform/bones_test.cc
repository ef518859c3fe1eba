#include "banmo/deform/bones.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
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

// The hand-written Jacobian of WarpWithJacobian (the blend and each bone's
// term) against its autodiff twin: the templated warp with Jets over (x, all
// bones, all transforms). Quaternions of unit norm and of norm 1.3 (the
// warps normalise them; a solver step leaves them off the unit sphere
// between manifold updates).
TEST(WarpWithJacobian, EqualsAutodiffTwin) {
  for (const double quaternion_norm : {1.0, 1.3}) {
    for (WarpDirection dir : {WarpDirection::kBackward, WarpDirection::kForward}) {
      Rig rig = RandomRig(3, 11, 0.4);
      for (int b = 0; b < 3; ++b) {
        for (int k = 0; k < 4; ++k) {
          rig.bones[kBoneSize * b + kBoneQw + k] *= quaternion_norm;
          rig.bones_t[kPoseSize * b + kPoseQw + k] *= quaternion_norm;
        }
      }
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
}

// With a cutoff, a bone whose weight at x is below it is left out of the
// derivatives: its columns are zero, the kept bones' columns are still
// exact, and d out / d x differs from the exact one by that bone's term
// w_b ((p_b - out) dl_b/dx + dp_b/dx) exactly. The value blends every bone.
TEST(WarpWithJacobian, CutoffLeavesOutOnlyTheFaintBonesTerms) {
  constexpr int kBones = 3;
  constexpr int kFaint = 2;
  constexpr double kCutoff = 1e-4;
  const double x[3] = {0.2, -0.1, 0.3};
  for (WarpDirection dir : {WarpDirection::kBackward, WarpDirection::kForward}) {
    Rig rig = RandomRig(kBones, 11, 0.4);
    // Move the faint bone away from x until its weight is in [1e-8, 1e-5].
    double weights[kBones];
    for (double shift = 0.0; shift < 5.0; shift += 0.01) {
      double* bone = rig.bones.data() + kBoneSize * kFaint;
      bone[kBoneCenter + 0] = x[0] + 0.3 + shift;
      double logits[kBones], point[3];
      for (int b = 0; b < kBones; ++b) {
        const double* rest = rig.bones.data() + kBoneSize * b;
        const double* pose = rig.bones_t.data() + kPoseSize * b;
        if (dir == WarpDirection::kBackward) {
          BackwardBoneTerm(rest, pose, x, &logits[b], point);
        } else {
          ForwardBoneTerm(rest, pose, x, &logits[b], point);
        }
      }
      SkinningWeights(kBones, logits, weights);
      if (weights[kFaint] <= 1e-5) break;
    }
    ASSERT_LE(weights[kFaint], 1e-5);
    ASSERT_GE(weights[kFaint], 1e-8);
    for (int b = 0; b < kBones; ++b) {
      if (b != kFaint) {
        ASSERT_GE(weights[b], kCutoff);
      }
    }

    double exact_value[3], cut_value[3];
    WarpJacobian exact, cut;
    WarpWithJacobian(dir, kBones, rig.bones.data(), rig.bones_t.data(), x, exact_value, &exact);
    WarpWithJacobian(dir, kBones, rig.bones.data(), rig.bones_t.data(), x, cut_value, &cut, nullptr,
                     kCutoff);
    // The faint bone's own term, with Jets over x.
    using J = ceres::Jet<double, 3>;
    J xj[3], rest[kBoneSize], pose[kPoseSize], logit, p[3];
    for (int k = 0; k < 3; ++k) xj[k] = J(x[k], k);
    for (int k = 0; k < kBoneSize; ++k) rest[k] = J(rig.bones[kBoneSize * kFaint + k]);
    for (int k = 0; k < kPoseSize; ++k) pose[k] = J(rig.bones_t[kPoseSize * kFaint + k]);
    if (dir == WarpDirection::kBackward) {
      BackwardBoneTerm(rest, pose, xj, &logit, p);
    } else {
      ForwardBoneTerm(rest, pose, xj, &logit, p);
    }
    for (int r = 0; r < 3; ++r) {
      EXPECT_EQ(cut_value[r], exact_value[r]);
      const double lever = p[r].a - exact_value[r];
      for (int c = 0; c < 3; ++c) {
        const double faint_term = weights[kFaint] * (lever * logit.v[c] + p[r].v[c]);
        EXPECT_NEAR(cut.d_x(r, c) + faint_term, exact.d_x(r, c), 1e-12);
        EXPECT_LT(std::abs(faint_term), 1e-3);  // a bone of weight <= 1e-5 at x
      }
      for (int c = 0; c < kBoneSize * kBones; ++c) {
        const double expected = c / kBoneSize == kFaint ? 0.0 : exact.d_bones(r, c);
        EXPECT_NEAR(cut.d_bones(r, c), expected, 1e-15) << c;
      }
      for (int c = 0; c < kPoseSize * kBones; ++c) {
        const double expected = c / kPoseSize == kFaint ? 0.0 : exact.d_bones_t(r, c);
        EXPECT_NEAR(cut.d_bones_t(r, c), expected, 1e-15) << c;
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

// Re-initialised bones keep the frame's motion: one rigid motion of every
// old bone is handed to every new bone exactly (with the sign of some old
// quaternions flipped, which is the same rotation), and in general each
// new centre lands where the old forward warp takes it.
TEST(TransferBoneMotion, KeepsOneRigidMotionExactly) {
  Rig old_rig = RandomRig(5, 4, 0.0);
  const Pose m =
      PoseFromAngleAxis(Eigen::Vector3d(0.9, -0.4, 1.2), Eigen::Vector3d(0.3, -0.5, 0.2));
  for (int b = 0; b < 5; ++b) {
    double* j = old_rig.bones_t.data() + kPoseSize * b;
    std::copy(m.data(), m.data() + kPoseSize, j);
    if (b % 2 == 1) {
      for (int k = 0; k < 4; ++k) j[kPoseQw + k] = -j[kPoseQw + k];
    }
  }
  const Rig new_rig = RandomRig(7, 9, 0.0);
  std::vector<double> new_t(kPoseSize * 7);
  TransferBoneMotion(5, old_rig.bones.data(), old_rig.bones_t.data(), 7, new_rig.bones.data(),
                     new_t.data());
  for (int k = 0; k < 7; ++k) {
    const double* j = new_t.data() + kPoseSize * k;
    const double sign = j[kPoseQw] * m[kPoseQw] < 0.0 ? -1.0 : 1.0;
    // A weighted mean of equal unit quaternions and a blend of equal points:
    // rounding only.
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(sign * j[kPoseQw + i], m[kPoseQw + i], 1e-14);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(j[kPoseT + i], m[kPoseT + i], 1e-14);
  }
}

TEST(TransferBoneMotion, NewCentresFollowTheOldForwardWarp) {
  const Rig old_rig = RandomRig(4, 21, 0.5);
  const Rig new_rig = RandomRig(6, 22, 0.0);
  std::vector<double> new_t(kPoseSize * 6);
  TransferBoneMotion(4, old_rig.bones.data(), old_rig.bones_t.data(), 6, new_rig.bones.data(),
                     new_t.data());
  for (int k = 0; k < 6; ++k) {
    const double* c = new_rig.bones.data() + kBoneSize * k + kBoneCenter;
    double expected[3], moved[3];
    ForwardWarp(4, old_rig.bones.data(), old_rig.bones_t.data(), c, expected);
    PoseTransformPoint(new_t.data() + kPoseSize * k, c, moved);
    const Eigen::Map<const Eigen::Vector4d> q(new_t.data() + kPoseSize * k + kPoseQw);
    EXPECT_NEAR(q.norm(), 1.0, 1e-14);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(moved[i], expected[i], 1e-14);
  }
  // A new bone on an old bone's centre, where that bone outweighs the rest
  // (small Gaussians far apart), takes that bone's rotation.
  Rig far = RandomRig(3, 5, 0.6);
  for (int b = 0; b < 3; ++b) {
    double* bone = far.bones.data() + kBoneSize * b;
    for (int i = 0; i < 3; ++i) bone[kBoneCenter + i] = i == 0 ? 2.0 * b : 0.0;
    for (int i = 0; i < 3; ++i) bone[kBoneLogScale + i] = std::log(0.1);
  }
  std::vector<double> one_t(kPoseSize * 3);
  TransferBoneMotion(3, far.bones.data(), far.bones_t.data(), 3, far.bones.data(), one_t.data());
  for (int b = 0; b < 3; ++b) {
    // Neighbours 2 apart at scale 0.1: weights below exp(-200) / 1.
    EXPECT_LT(
        RotationAngleBetween(one_t.data() + kPoseSize * b, far.bones_t.data() + kPoseSize * b),
        1e-12);
  }
}

// Turning every bone by M turns the mean by M (left multiplication is a
// linear isometry of the quaternions), whatever the signs of the inputs.
TEST(MeanBoneRotation, TurnsWithTheBones) {
  Rig rig = RandomRig(4, 31, 0.7);
  const double weights[4] = {0.1, 0.5, 0.3, 0.1};
  const Eigen::Vector4d before = MeanBoneRotation(4, rig.bones_t.data(), weights);
  const Pose m = PoseFromAngleAxis(Eigen::Vector3d(-1.1, 0.4, 2.0), Eigen::Vector3d(1, 2, 3));
  for (int b = 0; b < 4; ++b) {
    double* j = rig.bones_t.data() + kPoseSize * b;
    const Pose old = Eigen::Map<const Pose>(j);
    PoseCompose(m.data(), old.data(), j);
    if (b == 2) {
      for (int k = 0; k < 4; ++k) j[kPoseQw + k] = -j[kPoseQw + k];
    }
  }
  const Eigen::Vector4d after = MeanBoneRotation(4, rig.bones_t.data(), weights);
  const Eigen::Quaterniond expected =
      Eigen::Quaterniond(m[0], m[1], m[2], m[3]) *
      Eigen::Quaterniond(before[0], before[1], before[2], before[3]);
  EXPECT_NEAR(
      std::abs(after.dot(Eigen::Vector4d(expected.w(), expected.x(), expected.y(), expected.z()))),
      1.0, 1e-14);
}

TEST(TransferBoneMotion, IdentityWithoutOldBones) {
  const Rig new_rig = RandomRig(2, 3, 0.0);
  std::vector<double> new_t(kPoseSize * 2, 5.0);
  TransferBoneMotion(0, nullptr, nullptr, 2, new_rig.bones.data(), new_t.data());
  for (int k = 0; k < 2; ++k) {
    for (int i = 0; i < kPoseSize; ++i) EXPECT_EQ(new_t[kPoseSize * k + i], PoseIdentity()[i]);
  }
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
