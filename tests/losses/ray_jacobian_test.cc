// Residual-level regression tests of the ray loss terms: the mixed-mode,
// batched Jacobians (losses/ray_batch.h) against the full-Jet reference
// (losses/ray_reference.h) and against numeric differentiation.
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <memory>

#include "banmo/losses/ray_batch.h"
#include "banmo/losses/ray_reference.h"
#include "banmo/losses/test_scene.h"
#include "jacobian_test_util.h"

namespace banmo {
namespace {

using testing::EvaluateCost;
using testing::RelativeJacobianError;

// Both paths compute exact derivatives in double precision; they differ only
// in the order of summation (reverse-mode products against forward Jets), so
// they agree to rounding: 1e-9 relative to the largest entry leaves a margin
// of ~1e4 ulps for cancellation in sums of a few thousand terms.
constexpr double kReferenceTolerance = 1e-9;
// Batched and single-ray mixed-mode evaluation run the same arithmetic except
// for GEMM blocking: equal to 1e-12 relative.
constexpr double kBatchTolerance = 1e-12;

class RayTermJacobian : public ::testing::TestWithParam<LossTerm> {};

TEST_P(RayTermJacobian, MatchesFullJetReference) {
  const LossTerm term = GetParam();
  TestScene scene = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  for (int r = 0; r < batch.num_rays(); ++r) {
    ASSERT_TRUE(batch.rays()[r].HasTerm(term, batch.options().weights));
    auto mixed = batch.MakeCostFunction(r, term);
    auto reference = MakeReferenceCostFunction(batch, r, term);
    const std::vector<double*> params = batch.TermParameterBlocks(r, term);
    ASSERT_EQ(mixed->parameter_block_sizes(), reference->parameter_block_sizes());
    const auto a = EvaluateCost(*mixed, params);
    const auto b = EvaluateCost(*reference, params);
    ASSERT_TRUE(a.ok && b.ok);
    EXPECT_LT((a.residuals - b.residuals).cwiseAbs().maxCoeff(),
              1e-12 * std::max(1.0, b.residuals.cwiseAbs().maxCoeff()))
        << "ray " << r;
    EXPECT_GT(testing::MaxAbs(b), 0.0);
    EXPECT_LT(RelativeJacobianError(a, b), kReferenceTolerance) << "ray " << r;
  }
}

TEST_P(RayTermJacobian, BatchedCacheEqualsSingleRay) {
  const LossTerm term = GetParam();
  TestScene scene = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  batch.EvaluateAll(/*jacobians=*/true);
  ASSERT_TRUE(batch.cache_valid());
  for (int r = 0; r < batch.num_rays(); ++r) {
    auto cost = batch.MakeCostFunction(r, term);
    const std::vector<double*> params = batch.TermParameterBlocks(r, term);
    const auto cached = EvaluateCost(*cost, params);  // model pointers: served from the cache
    batch.Invalidate();
    const auto single = EvaluateCost(*cost, params);  // evaluated alone
    batch.EvaluateAll(true);
    EXPECT_LT((cached.residuals - single.residuals).cwiseAbs().maxCoeff(), 1e-13);
    EXPECT_LT(RelativeJacobianError(cached, single), kBatchTolerance) << "ray " << r;
  }
}

TEST_P(RayTermJacobian, AgreesWithNumericDifferentiation) {
  const LossTerm term = GetParam();
  TestScene scene = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  ceres::NumericDiffOptions numeric;
  // Softplus with beta = 100 is sharp: Ridders' extrapolation from a small
  // first step (DESIGN.md Sec. 5: the default 1e-2 gives false failures).
  numeric.ridders_relative_initial_step_size = 1e-4;
  for (int r = 0; r < 2; ++r) {
    auto cost = batch.MakeCostFunction(r, term);
    const std::vector<double*> params = batch.TermParameterBlocks(r, term);
    const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
    ceres::GradientChecker checker(cost.get(), no_manifolds, numeric);
    ceres::GradientChecker::ProbeResults results;
    // GradientChecker's own verdict is per entry (|a - b| / max(|a|, |b|)),
    // which flags entries near 1e-12 where numeric differences are noise.
    // We compare its two Jacobians norm-wise instead: max |J - J_numeric|
    // within 1e-6 of the largest entry, what Ridders' method resolves here.
    checker.Probe(params.data(), 1e-6, &results);
    double err = 0.0, scale = 0.0;
    for (size_t i = 0; i < results.jacobians.size(); ++i) {
      err = std::max(err,
                     (results.jacobians[i] - results.numeric_jacobians[i]).cwiseAbs().maxCoeff());
      scale = std::max(scale, results.numeric_jacobians[i].cwiseAbs().maxCoeff());
    }
    EXPECT_GT(scale, 0.0);
    EXPECT_LT(err, 1e-6 * scale) << "ray " << r << "\n" << results.error_log;
  }
}

INSTANTIATE_TEST_SUITE_P(AllTerms, RayTermJacobian,
                         ::testing::Values(LossTerm::kRgb, LossTerm::kSilhouette, LossTerm::kFlow,
                                           LossTerm::kFeatureMatch, LossTerm::kCycle2d,
                                           LossTerm::kCycle3d),
                         [](const ::testing::TestParamInfo<LossTerm>& info) {
                           return std::string(LossTermName(info.param));
                         });

}  // namespace
}  // namespace banmo
