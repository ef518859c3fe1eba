#include "banmo/losses/regularizers.h"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <random>

#include "banmo/deform/bones.h"
#include "banmo/losses/bone_inside_loss.h"
#include "banmo/losses/eikonal_loss.h"
#include "banmo/losses/pose_smoothness_loss.h"
#include "jacobian_test_util.h"

namespace banmo {
namespace {

using testing::EvaluateCost;
using testing::RelativeJacobianError;

// Exact derivatives on both sides, summed in different orders (see
// ray_jacobian_test.cc).
constexpr double kReferenceTolerance = 1e-9;

CanonicalFieldOptions TinyField() {
  CanonicalFieldOptions o;
  o.position_encoding.num_bands = 2;
  o.sdf_width = 8;
  o.sdf_layers = 2;
  o.color_width = 8;
  o.color_layers = 1;
  o.embedding_width = 8;
  o.embedding_layers = 1;
  o.init_sphere_radius = 0.3;
  return o;
}

struct Fixture {
  CanonicalField field{TinyField()};
  std::vector<double> sdf, color, embedding;
  Fixture() {
    sdf.resize(field.SdfParameterSize());
    color.resize(field.ColorParameterSize());
    embedding.resize(field.EmbeddingParameterSize());
    field.InitializeParameters(3, sdf.data(), color.data(), embedding.data());
    // Move away from the symmetric initialisation so every weight matters.
    std::mt19937 rng(5);
    std::normal_distribution<double> n(0.0, 0.05);
    for (double& w : sdf) w += n(rng);
  }
};

Eigen::Matrix3Xd RandomPoints(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  Eigen::Matrix3Xd p(3, n);
  for (int j = 0; j < n; ++j) p.col(j) << u(rng), u(rng), u(rng);
  return p;
}

TEST(EikonalLoss, HandValues) {
  const EikonalLoss loss(4.0);
  const double unit[3] = {0.6, 0.0, 0.8};
  const double doubled[3] = {0.0, 0.0, 2.0};
  double r;
  loss(unit, &r);
  EXPECT_NEAR(r, 0.0, 1e-12);
  loss(doubled, &r);
  EXPECT_NEAR(r, 2.0, 1e-12);  // sqrt(4) * (2 - 1)
  const double zero[3] = {0.0, 0.0, 0.0};
  loss(zero, &r);
  EXPECT_NEAR(r, -2.0, 1e-11);  // the norm floor eps = 1e-12 shifts it by 2e-12
}

TEST(EikonalCost, MatchesFullJetReference) {
  Fixture f;
  const Eigen::Matrix3Xd points = RandomPoints(6, 1);
  auto mixed = MakeEikonalCostFunction(f.field, points, 0.1);
  auto reference = MakeEikonalReferenceCostFunction(f.field, points, 0.1);
  std::vector<double*> params = {f.sdf.data()};
  const auto a = EvaluateCost(*mixed, params);
  const auto b = EvaluateCost(*reference, params);
  EXPECT_LT((a.residuals - b.residuals).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT(testing::MaxAbs(b), 0.0);
  EXPECT_LT(RelativeJacobianError(a, b), kReferenceTolerance);
}

// The geometric initialisation approximates |X| - r better the wider the
// network (SAL's construction is a mean-field argument): width 64 here.
CanonicalFieldOptions WideField() {
  CanonicalFieldOptions o = TinyField();
  o.sdf_width = 64;
  return o;
}

TEST(EikonalCost, NearZeroAtGeometricInitialisation) {
  CanonicalField field(WideField());
  std::vector<double> sdf(field.SdfParameterSize()), color(field.ColorParameterSize()),
      emb(field.EmbeddingParameterSize());
  field.InitializeParameters(3, sdf.data(), color.data(), emb.data());
  // The sphere initialisation is |X| - r only approximately (softplus
  // network of width 64): the gradient norm is within 0.15 of 1 away from
  // the origin.
  Eigen::Matrix3Xd points(3, 3);
  points << 0.5, 0.0, -0.4, 0.0, 0.6, 0.3, 0.2, 0.0, 0.4;
  auto cost = MakeEikonalCostFunction(field, points, 1.0);
  std::vector<double*> params = {sdf.data()};
  const auto e = EvaluateCost(*cost, params);
  EXPECT_LT(e.residuals.cwiseAbs().maxCoeff(), 0.15);
}

TEST(BoneInsideCost, MatchesFullJetReferenceAndHinge) {
  Fixture f;
  const int B = 4;
  std::vector<double> bones(kBoneSize * B);
  InitializeBones({Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.1, 0.05, 0),
                   Eigen::Vector3d(0.9, 0, 0), Eigen::Vector3d(0, -0.7, 0.3)},
                  0.1, bones.data());
  auto mixed = MakeBoneInsideCostFunction(f.field, B, 0.02, 1.0);
  auto reference = MakeBoneInsideReferenceCostFunction(f.field, B, 0.02, 1.0);
  std::vector<double*> params = {f.sdf.data(), bones.data()};
  const auto a = EvaluateCost(*mixed, params);
  const auto b = EvaluateCost(*reference, params);
  EXPECT_LT((a.residuals - b.residuals).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT(RelativeJacobianError(a, b), kReferenceTolerance);

  // Hinge values at the (unperturbed, wide) sphere initialisation: centres
  // inside the r = 0.3 sphere give zero, outside about |c| - r + margin.
  CanonicalField wide(WideField());
  std::vector<double> sdf(wide.SdfParameterSize()), color(wide.ColorParameterSize()),
      emb(wide.EmbeddingParameterSize());
  wide.InitializeParameters(3, sdf.data(), color.data(), emb.data());
  auto cost = MakeBoneInsideCostFunction(wide, B, 0.02, 1.0);
  std::vector<double*> wide_params = {sdf.data(), bones.data()};
  const auto h = EvaluateCost(*cost, wide_params);
  EXPECT_EQ(h.residuals[0], 0.0);
  EXPECT_EQ(h.residuals[1], 0.0);
  EXPECT_NEAR(h.residuals[2], 0.9 - 0.3 + 0.02, 0.1);  // init accuracy ~0.05
  EXPECT_GT(h.residuals[3], 0.3);
}

TEST(PoseSmoothness, ZeroForEqualPosesAndAngleForRotation) {
  const PoseSmoothnessLoss loss(1.0, 1.0);
  const Pose a = PoseFromAngleAxis(Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(1, 2, 3));
  double r[6];
  loss(a.data(), a.data(), r);
  for (double v : r) EXPECT_NEAR(v, 0.0, 1e-12);
  // b = a rotated by 0.25 rad about z (in a's frame), moved by (0.5, 0, 0).
  Pose step = PoseFromAngleAxis(Eigen::Vector3d(0, 0, 0.25), Eigen::Vector3d::Zero());
  Pose b;
  ceres::QuaternionProduct(a.data(), step.data(), b.data());
  b.tail<3>() = a.tail<3>() + Eigen::Vector3d(0.5, 0, 0);
  loss(a.data(), b.data(), r);
  EXPECT_NEAR(r[2], 0.25, 1e-12);
  EXPECT_NEAR(r[3], 0.5, 1e-12);
  // The quaternion's sign does not matter.
  Pose minus_b = b;
  minus_b.head<4>() *= -1.0;
  double r2[6];
  loss(a.data(), minus_b.data(), r2);
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(r[k], r2[k], 1e-12);
}

TEST(PoseSmoothness, CostFunctionsAgreeWithNumericDifferentiation) {
  const Pose ia = PoseFromAngleAxis(Eigen::Vector3d(0.3, 0, 0.1), Eigen::Vector3d(0, 0, 3));
  const Pose ib = PoseFromAngleAxis(Eigen::Vector3d(0.2, 0.1, 0.1), Eigen::Vector3d(0, 0.1, 3));
  Pose da = PoseFromAngleAxis(Eigen::Vector3d(0.05, -0.02, 0.01), Eigen::Vector3d(0.01, 0, 0));
  Pose db = PoseFromAngleAxis(Eigen::Vector3d(-0.03, 0.04, 0.02), Eigen::Vector3d(0, 0.02, 0));
  auto root = MakeRootSmoothnessCostFunction(ia, ib, 2.0, 0.5);
  const std::vector<const ceres::Manifold*>* none = nullptr;
  ceres::GradientChecker checker(root.get(), none, ceres::NumericDiffOptions());
  ceres::GradientChecker::ProbeResults results;
  std::vector<double*> params = {da.data(), db.data()};
  EXPECT_TRUE(checker.Probe(params.data(), 1e-7, &results)) << results.error_log;

  const int B = 2;
  std::vector<double> ja(kPoseSize * B), jb(kPoseSize * B);
  for (int b = 0; b < B; ++b) {
    const Pose p = PoseFromAngleAxis(Eigen::Vector3d(0.1 * b, 0.2, -0.1), Eigen::Vector3d(0, b, 0));
    const Pose q =
        PoseFromAngleAxis(Eigen::Vector3d(0.1 * b + 0.05, 0.1, 0), Eigen::Vector3d(0.1, b, 0));
    std::copy(p.data(), p.data() + kPoseSize, ja.data() + kPoseSize * b);
    std::copy(q.data(), q.data() + kPoseSize, jb.data() + kPoseSize * b);
  }
  auto bones = MakeBoneSmoothnessCostFunction(B, 1.0, 1.0);
  ceres::GradientChecker bone_checker(bones.get(), none, ceres::NumericDiffOptions());
  std::vector<double*> bone_params = {ja.data(), jb.data()};
  EXPECT_TRUE(bone_checker.Probe(bone_params.data(), 1e-7, &results)) << results.error_log;
}

TEST(BoneJointCost, ZeroForATurnAboutTheJointAndTheGapOtherwise) {
  // Two bones joined at m: bone 1 turned 40 deg about m (a bent joint) costs
  // nothing; bone 1 moved by d costs sqrt(w) |d| per joint.
  const Eigen::Vector3d m(0.2, -0.1, 0.05);
  const std::vector<BoneJoint> joints = {{0, 1, m}};
  const double w = 4.0;
  auto cost = MakeBoneJointCostFunction(2, joints, w);
  ASSERT_EQ(cost->num_residuals(), 3);
  std::vector<double> bones_t(2 * kPoseSize);
  PoseSetIdentity(bones_t.data());
  // J_1 = T(m) R T(-m): R about m.
  const Eigen::Isometry3d about_m =
      Eigen::Translation3d(m) *
      Eigen::AngleAxisd(40.0 * M_PI / 180.0, Eigen::Vector3d(1, 2, 3).normalized()) *
      Eigen::Translation3d(-m);
  const Pose bent = PoseFromIsometry(about_m);
  std::copy(bent.data(), bent.data() + kPoseSize, bones_t.data() + kPoseSize);
  const double* params[] = {bones_t.data()};
  double r[3];
  ASSERT_TRUE(cost->Evaluate(params, r, nullptr));
  EXPECT_LT(Eigen::Map<Eigen::Vector3d>(r).norm(), 1e-14);
  // Slide bone 1 by d instead.
  const Eigen::Vector3d d(0.03, -0.04, 0.0);
  PoseSetIdentity(bones_t.data() + kPoseSize);
  for (int k = 0; k < 3; ++k) bones_t[kPoseSize + kPoseT + k] = d[k];
  ASSERT_TRUE(cost->Evaluate(params, r, nullptr));
  EXPECT_NEAR(Eigen::Map<Eigen::Vector3d>(r).norm(), std::sqrt(w) * d.norm(), 1e-14);
  EXPECT_NEAR(r[0], -std::sqrt(w) * d[0], 1e-14);  // J_0 m - J_1 m
}

TEST(BoneJointCost, AgreesWithNumericDifferentiation) {
  const int B = 3;
  const std::vector<BoneJoint> joints = {{0, 1, Eigen::Vector3d(0.1, 0.2, -0.1)},
                                         {1, 2, Eigen::Vector3d(-0.3, 0.0, 0.2)}};
  auto cost = MakeBoneJointCostFunction(B, joints, 0.5);
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 0.3);
  std::vector<double> bones_t(B * kPoseSize);
  for (int b = 0; b < B; ++b) {
    const Pose p = PoseFromAngleAxis(Eigen::Vector3d(n(rng), n(rng), n(rng)),
                                     Eigen::Vector3d(n(rng), n(rng), n(rng)));
    std::copy(p.data(), p.data() + kPoseSize, bones_t.data() + kPoseSize * b);
  }
  const std::vector<const ceres::Manifold*>* none = nullptr;
  ceres::GradientChecker checker(cost.get(), none, ceres::NumericDiffOptions());
  ceres::GradientChecker::ProbeResults results;
  std::vector<double*> params = {bones_t.data()};
  EXPECT_TRUE(checker.Probe(params.data(), 1e-7, &results)) << results.error_log;
}

TEST(LossFunctors, HandComputedValues) {
  // Each functor's residual at a constructed solution is zero and at a
  // perturbed input equals the hand-computed value.
  double r[3];
  const BoneInsideLoss inside(0.05, 4.0);
  const double deep = -0.2, shallow = -0.01;
  inside(&deep, r);
  EXPECT_EQ(r[0], 0.0);
  inside(&shallow, r);
  EXPECT_NEAR(r[0], 2.0 * 0.04, 1e-15);
}

}  // namespace
}  // namespace banmo
