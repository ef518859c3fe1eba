// Delta skinning (Eq. 14): the warp's hand-written derivative wrt the delta
// logits, and MLP_Delta's batched Jacobian and weight gradients, against
// their autodiff twins (the templated single-point paths with Jets).
#include "banmo/deform/delta_skinning.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "banmo/deform/bones.h"
#include "banmo/util/error.h"

namespace banmo {
namespace {

constexpr int kBones = 4;

std::vector<double> RandomBones(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> bones(kBoneSize * kBones);
  std::vector<Eigen::Vector3d> centres;
  for (int b = 0; b < kBones; ++b)
    centres.emplace_back(0.5 * u(*rng), 0.5 * u(*rng), 0.5 * u(*rng));
  InitializeBones(centres, 0.3, bones.data());
  return bones;
}

std::vector<double> RandomTransforms(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> t(kPoseSize * kBones);
  for (int b = 0; b < kBones; ++b) {
    const Pose j = PoseFromAngleAxis(0.4 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng)),
                                     0.2 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng)));
    std::copy(j.data(), j.data() + kPoseSize, t.data() + kPoseSize * b);
  }
  return t;
}

// d out / d delta_logits of WarpWithJacobian against Jets over the logits.
TEST(DeltaSkinning, WarpDerivativeWrtDeltaLogitsEqualsAutodiff) {
  std::mt19937 rng(5);
  const std::vector<double> bones = RandomBones(&rng);
  const std::vector<double> bones_t = RandomTransforms(&rng);
  const double x[3] = {0.1, -0.2, 0.15};
  const double delta[kBones] = {0.7, -1.3, 0.2, 2.1};
  using J = ceres::Jet<double, kBones>;
  std::vector<J> bj(bones.begin(), bones.end()), tj(bones_t.begin(), bones_t.end());
  J xj[3] = {J(x[0]), J(x[1]), J(x[2])}, dj[kBones], out[3];
  for (int b = 0; b < kBones; ++b) dj[b] = J(delta[b], b);
  for (WarpDirection dir : {WarpDirection::kBackward, WarpDirection::kForward}) {
    if (dir == WarpDirection::kBackward) {
      BackwardWarp(kBones, bj.data(), tj.data(), xj, out, dj);
    } else {
      ForwardWarp(kBones, bj.data(), tj.data(), xj, out, dj);
    }
    double value[3];
    WarpJacobian jac;
    WarpWithJacobian(dir, kBones, bones.data(), bones_t.data(), x, value, &jac, delta);
    ASSERT_EQ(jac.d_delta_logits.cols(), kBones);
    for (int r = 0; r < 3; ++r) {
      EXPECT_NEAR(value[r], out[r].a, 1e-14);
      // Exact both ways; 1e-13 absolute on entries of order 0.1.
      for (int b = 0; b < kBones; ++b) EXPECT_NEAR(jac.d_delta_logits(r, b), out[r].v[b], 1e-13);
    }
    // Zero delta logits change nothing.
    const double zeros[kBones] = {0, 0, 0, 0};
    double with_zero[3], without[3];
    WarpWithJacobian(dir, kBones, bones.data(), bones_t.data(), x, with_zero, &jac, zeros);
    WarpWithJacobian(dir, kBones, bones.data(), bones_t.data(), x, without, &jac);
    for (int r = 0; r < 3; ++r) EXPECT_EQ(with_zero[r], without[r]);
  }
}

DeltaSkinningOptions SmallOptions() {
  DeltaSkinningOptions o;
  o.enabled = true;
  o.width = 8;
  o.hidden_layers = 2;
  o.num_bands = 2;
  o.pose_code_dim = 3;
  return o;
}

// Batched logits, local Jacobian d logits / d [x, code] and weight gradients
// against the templated single-point path with Jets.
TEST(DeltaSkinning, BatchedPassesEqualAutodiff) {
  const DeltaSkinning delta(SmallOptions(), kBones);
  std::vector<double> params(delta.NumParameters());
  delta.InitializeParameters(3, params.data());
  EXPECT_TRUE(delta.IsZero(params.data()));
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double& p : params) p += 0.3 * u(rng);  // all layers non-zero
  EXPECT_FALSE(delta.IsZero(params.data()));

  const int n = 5, P = delta.CodeDim(), L = delta.LocalDim();
  DeltaSkinningBatch batch;
  batch.x = Eigen::Matrix3Xd::Random(3, n) * 0.8;
  batch.codes = Eigen::MatrixXd::Random(P, n);
  delta.ForwardBatch(params.data(), &batch, /*jacobian=*/true);
  ASSERT_EQ(batch.logits.rows(), kBones);
  ASSERT_EQ(batch.jacobian.cols(), L * n);

  // Local Jacobian: Jets over [x, code].
  for (int j = 0; j < n; ++j) {
    using J = ceres::Jet<double, 6>;  // 3 + P = 6
    ASSERT_EQ(L, 6);
    J x[3], code[3], out[kBones];
    for (int c = 0; c < 3; ++c) x[c] = J(batch.x(c, j), c);
    for (int c = 0; c < P; ++c) code[c] = J(batch.codes(c, j), 3 + c);
    delta.Logits(params.data(), x, code, out);
    for (int b = 0; b < kBones; ++b) {
      // Same arithmetic up to GEMM order: 1e-12 relative-ish on O(1) values.
      EXPECT_NEAR(batch.logits(b, j), out[b].a, 1e-12);
      for (int k = 0; k < L; ++k) EXPECT_NEAR(batch.jacobian(b, L * j + k), out[b].v[k], 1e-11);
    }
  }

  // Weight gradients of two groups against Jets over every weight.
  const Eigen::MatrixXd d_logits = Eigen::MatrixXd::Random(kBones, n);
  Eigen::MatrixXd d_params;
  delta.BackwardBatch(params.data(), batch, d_logits, {0, 2, n}, &d_params);
  ASSERT_EQ(d_params.cols(), 2);
  const int np = delta.NumParameters();
  Eigen::MatrixXd expected = Eigen::MatrixXd::Zero(np, 2);
  // Chunks of 16 weight directions.
  using J16 = ceres::Jet<double, 16>;
  for (int start = 0; start < np; start += 16) {
    std::vector<J16> pj(np);
    for (int k = 0; k < np; ++k) pj[k] = J16(params[k]);
    for (int k = start; k < std::min(np, start + 16); ++k) pj[k].v[k - start] = 1.0;
    for (int j = 0; j < n; ++j) {
      J16 x[3], code[3], out[kBones];
      for (int c = 0; c < 3; ++c) x[c] = J16(batch.x(c, j));
      for (int c = 0; c < P; ++c) code[c] = J16(batch.codes(c, j));
      delta.Logits(pj.data(), x, code, out);
      const int g = j < 2 ? 0 : 1;
      for (int b = 0; b < kBones; ++b) {
        for (int k = start; k < std::min(np, start + 16); ++k) {
          expected(k, g) += d_logits(b, j) * out[b].v[k - start];
        }
      }
    }
  }
  EXPECT_LT((d_params - expected).cwiseAbs().maxCoeff(), 1e-11 * expected.cwiseAbs().maxCoeff());
}

TEST(DeltaSkinning, OptionsAreChecked) {
  DeltaSkinningOptions o = SmallOptions();
  EXPECT_NO_THROW(o.Check());
  o.width = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = SmallOptions();
  o.pose_code_dim = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = SmallOptions();
  o.hidden_layers = 0;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace banmo
