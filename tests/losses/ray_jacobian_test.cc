// Residual-level regression tests of the ray loss terms: the mixed-mode,
// batched Jacobians (losses/ray_batch.h) against the full-Jet reference
// (losses/ray_reference.h) and against numeric differentiation.
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>

#include "banmo/deform/bones.h"
#include "banmo/losses/ray_batch.h"
#include "banmo/losses/ray_reference.h"
#include "banmo/losses/sample_weight.h"
#include "banmo/util/error.h"
#include "common/test_scene.h"
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

// Numeric differentiation (Ridders' method over every parameter of a term's
// blocks, MLP weights included) is by far the slowest check here: about 46 s
// per term and ray under AddressSanitizer. In the sanitizer build
// (BANMO_SANITIZE_BUILD, tests/losses/CMakeLists.txt) the memory and UB
// checks need its code path, not every term: it runs on ray 0 of the first
// per-ray term only, while every term's Jacobian is still held to the
// full-Jet reference and the batched cache there. The Release build runs the
// full set; BANMO_FULL_NUMERIC=1 runs it under the sanitizers too.
bool NumericSubset() {
#ifdef BANMO_SANITIZE_BUILD
  const char* full = std::getenv("BANMO_FULL_NUMERIC");
  return full == nullptr || std::string(full) != "1";
#else
  return false;
#endif
}

// The batch's cached evaluation of each ray's `term` against the same ray
// evaluated alone (kBatchTolerance).
void ExpectBatchedCacheEqualsSingleRay(RayBatch& batch, LossTerm term) {
  batch.EvaluateAll(/*jacobians=*/true);
  ASSERT_TRUE(batch.cache_valid());
  for (int r = 0; r < batch.num_rays(); ++r) {
    auto cost = batch.MakeCostFunction(r, term);
    const std::vector<double*> params = batch.TermParameterBlocks(r, term);
    const auto cached = EvaluateCost(*cost, params);  // model pointers: served from the cache
    batch.Invalidate();
    const auto single = EvaluateCost(*cost, params);  // evaluated alone
    batch.EvaluateAll(true);
    EXPECT_LT((cached.residuals - single.residuals).cwiseAbs().maxCoeff(), 1e-13)
        << LossTermName(term) << " ray " << r;
    EXPECT_LT(RelativeJacobianError(cached, single), kBatchTolerance)
        << LossTermName(term) << " ray " << r;
  }
}

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
  TestScene scene = MakeTestScene(TestSceneOptions());
  ExpectBatchedCacheEqualsSingleRay(*scene.batch, GetParam());
}

TEST_P(RayTermJacobian, AgreesWithNumericDifferentiation) {
  const LossTerm term = GetParam();
  if (NumericSubset() && term != RayTerms().front()) {
    GTEST_SKIP() << "sanitizer build: numeric differentiation of the first term only";
  }
  TestScene scene = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  ceres::NumericDiffOptions numeric;
  // Softplus with beta = 100 is sharp: Ridders' extrapolation from a small
  // first step (docs/design.md: the default 1e-2 gives false failures).
  numeric.ridders_relative_initial_step_size = 1e-4;
  for (int r = 0; r < (NumericSubset() ? 1 : 2); ++r) {
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

INSTANTIATE_TEST_SUITE_P(AllTerms, RayTermJacobian, ::testing::ValuesIn(RayTerms()),
                         [](const ::testing::TestParamInfo<LossTerm>& info) {
                           return std::string(LossTermName(info.param));
                         });

// The same three checks with delta skinning on (MLP_Delta logits in every
// warp, Eq. 14), plus a per-block check of the delta blocks relative to their
// own largest entry, so a wrong delta Jacobian cannot hide behind larger
// blocks in the global relative error.
class DeltaSkinningJacobian : public ::testing::TestWithParam<LossTerm> {};

TestSceneOptions DeltaSceneOptions() {
  TestSceneOptions o;
  o.delta_skinning = true;
  return o;
}

TEST_P(DeltaSkinningJacobian, MatchesFullJetReferencePerBlock) {
  const LossTerm term = GetParam();
  TestScene scene = MakeTestScene(DeltaSceneOptions());
  RayBatch& batch = *scene.batch;
  ASSERT_TRUE(scene.model->DeltaSkinningIsNonZero());
  int delta_blocks_seen = 0;
  for (int r = 0; r < batch.num_rays(); ++r) {
    auto mixed = batch.MakeCostFunction(r, term);
    auto reference = MakeReferenceCostFunction(batch, r, term);
    const std::vector<double*> params = batch.TermParameterBlocks(r, term);
    const std::vector<RayBlock> blocks = batch.TermBlocks(r, term);
    ASSERT_EQ(mixed->parameter_block_sizes(), reference->parameter_block_sizes());
    const auto a = EvaluateCost(*mixed, params);
    const auto b = EvaluateCost(*reference, params);
    ASSERT_TRUE(a.ok && b.ok);
    EXPECT_LT((a.residuals - b.residuals).cwiseAbs().maxCoeff(),
              1e-12 * std::max(1.0, b.residuals.cwiseAbs().maxCoeff()))
        << "ray " << r;
    EXPECT_LT(RelativeJacobianError(a, b), kReferenceTolerance) << "ray " << r;
    for (size_t i = 0; i < blocks.size(); ++i) {
      if (blocks[i] != kBlockDeltaSkin && blocks[i] != kBlockPoseCode &&
          blocks[i] != kBlockRestPoseCode) {
        continue;
      }
      ++delta_blocks_seen;
      const double scale = b.jacobians[i].cwiseAbs().maxCoeff();
      EXPECT_GT(scale, 0.0) << RayBlockName(blocks[i]) << " ray " << r;
      EXPECT_LT((a.jacobians[i] - b.jacobians[i]).cwiseAbs().maxCoeff(),
                kReferenceTolerance * scale)
          << RayBlockName(blocks[i]) << " ray " << r;
    }
  }
  EXPECT_GE(delta_blocks_seen, 2 * batch.num_rays());
}

TEST_P(DeltaSkinningJacobian, BatchedCacheEqualsSingleRay) {
  TestScene scene = MakeTestScene(DeltaSceneOptions());
  ExpectBatchedCacheEqualsSingleRay(*scene.batch, GetParam());
}

TEST_P(DeltaSkinningJacobian, AgreesWithNumericDifferentiation) {
  const LossTerm term = GetParam();
  if (NumericSubset() && term != RayTerms().front()) {
    GTEST_SKIP() << "sanitizer build: numeric differentiation of the first term only";
  }
  TestScene scene = MakeTestScene(DeltaSceneOptions());
  RayBatch& batch = *scene.batch;
  ceres::NumericDiffOptions numeric;
  numeric.ridders_relative_initial_step_size = 1e-4;  // as above
  auto cost = batch.MakeCostFunction(0, term);
  const std::vector<double*> params = batch.TermParameterBlocks(0, term);
  const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
  ceres::GradientChecker checker(cost.get(), no_manifolds, numeric);
  ceres::GradientChecker::ProbeResults results;
  checker.Probe(params.data(), 1e-6, &results);
  double err = 0.0, scale = 0.0;
  for (size_t i = 0; i < results.jacobians.size(); ++i) {
    err =
        std::max(err, (results.jacobians[i] - results.numeric_jacobians[i]).cwiseAbs().maxCoeff());
    scale = std::max(scale, results.numeric_jacobians[i].cwiseAbs().maxCoeff());
  }
  EXPECT_GT(scale, 0.0);
  EXPECT_LT(err, 1e-6 * scale) << results.error_log;
}

// With delta skinning switched off in the batch (allowed while MLP_Delta's
// output layer is zero), the terms carry no delta blocks and evaluate exactly
// as with it on.
TEST(DeltaSkinning, OffEqualsOnWhileTheOutputLayerIsZero) {
  TestScene scene = MakeTestScene(DeltaSceneOptions());
  Model& model = *scene.model;
  const Mlp& mlp = model.delta_skinning()->mlp();
  const int last = mlp.NumLinearLayers() - 1;
  std::fill(model.delta_skinning_params() + mlp.WeightOffset(last),
            model.delta_skinning_params() + mlp.NumParameters(), 0.0);
  ASSERT_FALSE(model.DeltaSkinningIsNonZero());
  RayBatch& batch = *scene.batch;
  batch.EvaluateAll(false);
  std::vector<double> on;
  for (int r = 0; r < batch.num_rays(); ++r) {
    const auto& res = batch.evaluation(r).residuals;
    on.insert(on.end(), res.begin(), res.end());
  }
  batch.SetDeltaSkinning(false);
  for (int r = 0; r < batch.num_rays(); ++r) {
    for (RayBlock b : batch.TermBlocks(r, LossTerm::kFlow)) {
      EXPECT_NE(b, kBlockDeltaSkin);
      EXPECT_NE(b, kBlockPoseCode);
    }
  }
  batch.EvaluateAll(false);
  std::vector<double> off;
  for (int r = 0; r < batch.num_rays(); ++r) {
    const auto& res = batch.evaluation(r).residuals;
    off.insert(off.end(), res.begin(), res.end());
  }
  ASSERT_EQ(on.size(), off.size());
  for (size_t k = 0; k < on.size(); ++k) EXPECT_EQ(on[k], off[k]) << k;
}

// Ray::silhouette_weight (sampling.unbiased_silhouette) multiplies the
// silhouette term's weight: its residual and Jacobian rows scale by the
// square root, and no other term changes.
TestSceneOptions SilhouetteWeightOptions(double weight) {
  TestSceneOptions o;
  o.silhouette_weight = weight;
  return o;
}

TestSceneOptions NeusOptions() {
  TestSceneOptions o;
  o.density = DensityModel::kNeus;
  return o;
}

// model.density neus: every term's mixed-mode Jacobian matches the full-Jet
// reference and the batched cache (the NeuS weights' own Jets are checked
// against differences in tests/volume), and the residuals differ from
// VolSDF's (the option reaches the pipeline).
TEST(RayBatch, NeusDensityMatchesFullJetReference) {
  TestScene scene = MakeTestScene(NeusOptions());
  TestScene volsdf = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  for (LossTerm term : RayTerms()) {
    for (int r = 0; r < batch.num_rays(); ++r) {
      auto mixed = batch.MakeCostFunction(r, term);
      auto reference = MakeReferenceCostFunction(batch, r, term);
      const std::vector<double*> params = batch.TermParameterBlocks(r, term);
      const auto a = EvaluateCost(*mixed, params);
      const auto b = EvaluateCost(*reference, params);
      ASSERT_TRUE(a.ok && b.ok);
      EXPECT_LT((a.residuals - b.residuals).cwiseAbs().maxCoeff(),
                1e-12 * std::max(1.0, b.residuals.cwiseAbs().maxCoeff()))
          << LossTermName(term) << " ray " << r;
      EXPECT_LT(RelativeJacobianError(a, b), kReferenceTolerance)
          << LossTermName(term) << " ray " << r;
      const auto v = EvaluateCost(*volsdf.batch->MakeCostFunction(r, term),
                                  volsdf.batch->TermParameterBlocks(r, term));
      if (term == LossTerm::kSilhouette) {
        EXPECT_GT((a.residuals - v.residuals).cwiseAbs().maxCoeff(), 1e-6) << "ray " << r;
      }
    }
  }
  for (LossTerm term : RayTerms()) ExpectBatchedCacheEqualsSingleRay(batch, term);
}

// Samples of weight below kMinWarpTau (losses/sample_weight.h) are left out
// of the colour, the flow, the 3D cycle and the rendered embedding, and the
// pipeline skips their colour MLP, embedding MLP and forward warps. A sharper
// density (SharpenDensityUntilSomeSamplesSkip, tests/common) leaves some of
// the rays' samples under the bound. Colour, flow, 3D cycle and rendered
// embedding still match the full-Jet reference, which evaluates and warps
// every sample and leaves them out in the functors; the 3D-cycle rows of the
// skipped samples are 0. With and without delta skinning (its forward logits
// are computed for every sample and read only for the warped ones), and
// with the rendered embedding moving the embedding alone.
TEST(RayBatch, SamplesOfNegligibleWeightMatchFullJetReference) {
  struct Variant {
    bool delta, embedding_only;
  };
  for (const Variant v : {Variant{false, false}, Variant{true, false}, Variant{false, true}}) {
    const bool delta = v.delta;
    TestSceneOptions options = delta ? DeltaSceneOptions() : TestSceneOptions();
    options.feature_render_embedding_only = v.embedding_only;
    options.hold_cycle_tau = false;  // the weights follow log beta below
    TestScene scene = MakeTestScene(options);
    RayBatch& batch = *scene.batch;
    const SampleWeightSplit split = SharpenDensityUntilSomeSamplesSkip(scene);
    ASSERT_GE(split.skipped, 4);
    ASSERT_GE(split.counted, 4);
    for (int r = 0; r < batch.num_rays(); ++r) {
      const RayEvaluation& ev = batch.evaluation(r);
      const int row = ev.term_row[static_cast<int>(LossTerm::kCycle3d)];
      ASSERT_GE(row, 0);
      for (size_t i = 0; i < ev.tau.size(); ++i) {
        if (WarpsSample(ev.tau[i])) continue;
        for (int c = 0; c < 3; ++c) EXPECT_EQ(ev.residuals[row + 3 * i + c], 0.0);
      }
    }
    for (LossTerm term :
         {LossTerm::kRgb, LossTerm::kFlow, LossTerm::kCycle3d, LossTerm::kFeatureRender}) {
      for (int r = 0; r < batch.num_rays(); ++r) {
        const std::string what = std::string(LossTermName(term)) + " ray " + std::to_string(r) +
                                 (delta ? " (delta)" : "") +
                                 (v.embedding_only ? " (embedding only)" : "");
        const std::vector<double*> params = batch.TermParameterBlocks(r, term);
        const auto a = EvaluateCost(*batch.MakeCostFunction(r, term), params);
        const auto b = EvaluateCost(*MakeReferenceCostFunction(batch, r, term), params);
        ASSERT_TRUE(a.ok && b.ok) << what;
        EXPECT_LT((a.residuals - b.residuals).cwiseAbs().maxCoeff(),
                  1e-12 * std::max(1.0, b.residuals.cwiseAbs().maxCoeff()))
            << what;
        EXPECT_GT(testing::MaxAbs(b), 0.0) << what;
        EXPECT_LT(RelativeJacobianError(a, b), kReferenceTolerance) << what;
      }
      ExpectBatchedCacheEqualsSingleRay(batch, term);
    }
  }
}

// losses.feature_render_embedding_only: the rendered-embedding term's
// Jacobian matches the full-Jet reference (rendering weights and sample
// points held at their values there too) and is zero in every block but the
// embedding MLP's, where it equals the full term's; every other term is
// unchanged.
TEST(RayBatch, FeatureRenderEmbeddingOnlyMovesOnlyTheEmbedding) {
  TestSceneOptions o;
  o.feature_render_embedding_only = true;
  TestScene scene = MakeTestScene(o);
  TestScene full = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  int rays_with_term = 0;
  for (LossTerm term : RayTerms()) {
    for (int r = 0; r < batch.num_rays(); ++r) {
      if (!batch.rays()[r].HasTerm(term, batch.options().weights)) continue;
      const std::vector<double*> params = batch.TermParameterBlocks(r, term);
      const auto a = EvaluateCost(*batch.MakeCostFunction(r, term), params);
      const auto b = EvaluateCost(*MakeReferenceCostFunction(batch, r, term), params);
      const auto f = EvaluateCost(*full.batch->MakeCostFunction(r, term),
                                  full.batch->TermParameterBlocks(r, term));
      ASSERT_TRUE(a.ok && b.ok && f.ok);
      EXPECT_LT(RelativeJacobianError(a, b), kReferenceTolerance)
          << LossTermName(term) << " ray " << r;
      EXPECT_EQ(a.residuals, f.residuals) << LossTermName(term) << " ray " << r;
      for (size_t i = 0; i < params.size(); ++i) {
        const bool embedding = params[i] == scene.model->embedding();
        if (term != LossTerm::kFeatureRender || embedding) {
          EXPECT_LT((a.jacobians[i] - f.jacobians[i]).cwiseAbs().maxCoeff(),
                    1e-12 * std::max(1.0, f.jacobians[i].cwiseAbs().maxCoeff()))
              << LossTermName(term) << " ray " << r << " block " << i;
        } else {
          EXPECT_EQ(a.jacobians[i].cwiseAbs().maxCoeff(), 0.0) << "ray " << r << " block " << i;
          if (term == LossTerm::kFeatureRender) {
            rays_with_term += f.jacobians[i].cwiseAbs().maxCoeff() > 0 ? 1 : 0;
          }
        }
      }
    }
  }
  EXPECT_GT(rays_with_term, 0) << "the full term moves other blocks";
  for (LossTerm term : RayTerms()) ExpectBatchedCacheEqualsSingleRay(batch, term);
}

TEST(RayBatch, SilhouetteWeightScalesOnlyTheSilhouetteRows) {
  TestScene plain = MakeTestScene(SilhouetteWeightOptions(1.0));
  TestScene weighted = MakeTestScene(SilhouetteWeightOptions(4.0));
  for (LossTerm term : RayTerms()) {
    const double scale = term == LossTerm::kSilhouette ? 2.0 : 1.0;
    for (int r = 0; r < plain.batch->num_rays(); ++r) {
      const auto a = EvaluateCost(*plain.batch->MakeCostFunction(r, term),
                                  plain.batch->TermParameterBlocks(r, term));
      const auto b = EvaluateCost(*weighted.batch->MakeCostFunction(r, term),
                                  weighted.batch->TermParameterBlocks(r, term));
      ASSERT_TRUE(a.ok && b.ok);
      ASSERT_EQ(a.residuals.size(), b.residuals.size());
      EXPECT_LT((b.residuals - scale * a.residuals).cwiseAbs().maxCoeff(),
                1e-14 * std::max(1.0, a.residuals.cwiseAbs().maxCoeff()))
          << LossTermName(term) << " ray " << r;
      ASSERT_EQ(a.jacobians.size(), b.jacobians.size());
      for (size_t k = 0; k < a.jacobians.size(); ++k) {
        if (a.jacobians[k].size() == 0) continue;
        EXPECT_LT((b.jacobians[k] - scale * a.jacobians[k]).cwiseAbs().maxCoeff(),
                  1e-13 * std::max(1.0, a.jacobians[k].cwiseAbs().maxCoeff()))
            << LossTermName(term) << " ray " << r << " block " << k;
      }
    }
  }
}

// Without field Jacobians (the pose solves) the residuals and every other
// block's Jacobian are the same bits; the MLP-weight blocks have none.
TEST(RayBatch, FieldJacobiansOffKeepsEveryOtherBlock) {
  for (bool delta : {false, true}) {
    const TestSceneOptions options = delta ? DeltaSceneOptions() : TestSceneOptions();
    TestScene with = MakeTestScene(options);
    TestScene without = MakeTestScene(options);
    with.batch->EvaluateAll(true);
    without.batch->SetFieldJacobians(false);
    without.batch->EvaluateAll(true);
    for (int r = 0; r < with.batch->num_rays(); ++r) {
      const RayEvaluation& a = with.batch->evaluation(r);
      const RayEvaluation& b = without.batch->evaluation(r);
      EXPECT_EQ(a.residuals, b.residuals);
      for (int k = 0; k < kNumRayBlocks; ++k) {
        const bool field =
            k == kBlockSdf || k == kBlockColor || k == kBlockEmbedding || k == kBlockDeltaSkin;
        if (field) {
          EXPECT_EQ(b.jacobians[k].cols(), 0) << RayBlockName(static_cast<RayBlock>(k));
        } else {
          EXPECT_TRUE(a.jacobians[k] == b.jacobians[k]) << RayBlockName(static_cast<RayBlock>(k));
        }
      }
    }
  }
}

// Without held 3D-cycle weights (RayBatchOptions::hold_cycle_tau false, the
// Adam stages) SetRays skips the forward pass; an evaluation at SetRays'
// parameters takes the same tau_i from its own composite, without their
// derivative, so residuals and Jacobians equal the held batch's to rounding
// (the same double operations, in a batch with or without Jacobians:
// 1e-12 relative). Away from that point the held batch keeps the old
// weights and the other follows the parameters: it equals a held batch
// rebuilt there.
TEST(RayBatch, OwnCycleTauEqualsHeldAtSetRaysParameters) {
  for (bool delta : {false, true}) {
    TestSceneOptions options = delta ? DeltaSceneOptions() : TestSceneOptions();
    TestScene held = MakeTestScene(options);
    options.hold_cycle_tau = false;
    TestScene own = MakeTestScene(options);
    const int rays = held.batch->num_rays();
    for (int r = 0; r < rays; ++r) {
      ASSERT_FALSE(held.batch->rays()[r].cycle_tau.empty());
      ASSERT_TRUE(own.batch->rays()[r].cycle_tau.empty());
    }
    auto expect_near = [](const Eigen::VectorXd& a, const Eigen::VectorXd& b, double tolerance,
                          const std::string& what) {
      ASSERT_EQ(a.size(), b.size()) << what;
      EXPECT_LE((a - b).cwiseAbs().maxCoeff(), tolerance * std::max(1.0, b.cwiseAbs().maxCoeff()))
          << what;
    };
    for (int r = 0; r < rays; ++r) {
      const std::string what = "ray " + std::to_string(r) + (delta ? " (delta)" : "");
      auto a = EvaluateCost(*own.batch->MakeCostFunction(r, LossTerm::kCycle3d),
                            own.batch->TermParameterBlocks(r, LossTerm::kCycle3d));
      auto b = EvaluateCost(*held.batch->MakeCostFunction(r, LossTerm::kCycle3d),
                            held.batch->TermParameterBlocks(r, LossTerm::kCycle3d));
      ASSERT_TRUE(a.ok && b.ok);
      expect_near(a.residuals, b.residuals, 1e-12, what);
      EXPECT_LT(RelativeJacobianError(a, b), 1e-12) << what;
      // The full-Jet twin with the same empty cycle_tau.
      auto c = EvaluateCost(*MakeReferenceCostFunction(*own.batch, r, LossTerm::kCycle3d),
                            own.batch->TermParameterBlocks(r, LossTerm::kCycle3d));
      ASSERT_TRUE(c.ok);
      expect_near(a.residuals, c.residuals, 1e-12, what + " reference");
      EXPECT_LT(RelativeJacobianError(a, c), kReferenceTolerance) << what << " reference";
    }
    // Another point: the SDF moved.
    for (TestScene* s : {&held, &own}) {
      for (int k = 0; k < s->model->sdf_size(); ++k) {
        s->model->sdf()[k] += 0.05 * std::sin(1.0 + k);
      }
      s->batch->Invalidate();
      s->batch->EvaluateAll(false);
    }
    std::vector<Ray> rebuilt = held.batch->rays();
    for (Ray& ray : rebuilt) ray.cycle_tau.clear();
    options.hold_cycle_tau = true;
    TestScene again = MakeTestScene(options);
    for (int k = 0; k < again.model->sdf_size(); ++k) {
      again.model->sdf()[k] = held.model->sdf()[k];
    }
    again.batch->SetRays(std::move(rebuilt));
    again.batch->EvaluateAll(false);
    double moved = 0.0;
    for (int r = 0; r < rays; ++r) {
      const int row = own.batch->evaluation(r).term_row[static_cast<int>(LossTerm::kCycle3d)];
      ASSERT_GE(row, 0);
      const int n = LossTermResiduals(LossTerm::kCycle3d, own.batch->rays()[r].NumSamples());
      auto rows = [&](const RayBatch& batch) {
        return Eigen::Map<const Eigen::VectorXd>(batch.evaluation(r).residuals.data() + row, n)
            .eval();
      };
      expect_near(rows(*own.batch), rows(*again.batch), 1e-12,
                  "moved ray " + std::to_string(r) + (delta ? " (delta)" : ""));
      moved = std::max(moved, (rows(*own.batch) - rows(*held.batch)).cwiseAbs().maxCoeff());
    }
    EXPECT_GT(moved, 1e-6) << "the held weights did not stay at the old point";
  }
}

// A batch without the rgb term evaluated without derivatives (the
// importance pass's coarse evaluation) runs the SDF MLP alone: its rendering
// weights, SDF values and silhouette residuals are the same bits as those of
// a batch with every term.
TEST(RayBatch, EvaluationWithoutColourKeepsWeightsAndSilhouette) {
  for (bool delta : {false, true}) {
    TestSceneOptions options = delta ? DeltaSceneOptions() : TestSceneOptions();
    TestScene all = MakeTestScene(options);
    options.weights = RayLossWeights::Only({LossTerm::kSilhouette});
    TestScene silhouette = MakeTestScene(options);
    all.batch->EvaluateAll(false);
    silhouette.batch->EvaluateAll(false);
    for (int r = 0; r < all.batch->num_rays(); ++r) {
      const RayEvaluation& a = all.batch->evaluation(r);
      const RayEvaluation& b = silhouette.batch->evaluation(r);
      EXPECT_EQ(a.tau, b.tau) << "ray " << r;
      EXPECT_EQ(a.sdf, b.sdf) << "ray " << r;
      const int row_a = a.term_row[static_cast<int>(LossTerm::kSilhouette)];
      const int row_b = b.term_row[static_cast<int>(LossTerm::kSilhouette)];
      ASSERT_GE(row_a, 0);
      ASSERT_GE(row_b, 0);
      EXPECT_EQ(a.residuals[row_a], b.residuals[row_b]) << "ray " << r;
    }
  }
}

// The solver's default skinning-Jacobian cutoff (RayBatchOptions) leaves
// out the derivatives of bones whose weight at a point is below it: with 12
// small bones many samples have such bones, the residuals are unchanged and
// every term's Jacobian stays within 1e-2 of its largest entry of the exact
// one. Tolerance: a left-out bone's term is w_b ((p_b - out) dl_b + dp_b)
// with w_b < 1e-4; near the cutoff its logit is about ln(1e4) = 9.2 below
// the largest, so |dl_b/dx| is about sqrt(2 x 9.2) / s = 61 for these bones
// of scale s = 0.07, and with |p_b - out| < 0.5 one bone moves an entry by
// up to about 3e-3 (measured: at most 1.1e-3 here).
TEST(RayBatch, SkinningJacobianCutoffChangesOnlyFaintBonesDerivatives) {
  TestSceneOptions o;
  o.num_bones = 12;
  TestScene exact = MakeTestScene(o);
  o.skinning_jacobian_cutoff = RayBatchOptions().skinning_jacobian_cutoff;
  ASSERT_GT(o.skinning_jacobian_cutoff, 0.0);
  TestScene cut = MakeTestScene(o);
  // Small bones (scale ~0.07): skinning weights far below the cutoff at
  // most samples for most bones.
  for (TestScene* scene : {&exact, &cut}) {
    Model& m = *scene->model;
    for (int b = 0; b < m.num_bones(); ++b) {
      for (int k = 0; k < 3; ++k) m.bones()[kBoneSize * b + kBoneLogScale + k] -= 1.5;
    }
    scene->batch->Invalidate();
  }
  double largest_difference = 0.0;
  for (LossTerm term : RayTerms()) {
    for (int r = 0; r < exact.batch->num_rays(); ++r) {
      auto a = EvaluateCost(*exact.batch->MakeCostFunction(r, term),
                            exact.batch->TermParameterBlocks(r, term));
      auto b = EvaluateCost(*cut.batch->MakeCostFunction(r, term),
                            cut.batch->TermParameterBlocks(r, term));
      ASSERT_TRUE(a.ok && b.ok);
      EXPECT_EQ(a.residuals, b.residuals) << LossTermName(term) << " ray " << r;
      const double err = RelativeJacobianError(b, a);
      EXPECT_LT(err, 1e-2) << LossTermName(term) << " ray " << r;
      largest_difference = std::max(largest_difference, err);
    }
  }
  EXPECT_GT(largest_difference, 0.0) << "the cutoff left out no bone: the test checks nothing";
}

TEST(RayBatchOptions, RejectsASkinningJacobianCutoffOutsideZeroToOne) {
  for (double bad : {-1e-9, 1.0, std::nan("")}) {
    RayBatchOptions o;
    o.skinning_jacobian_cutoff = bad;
    EXPECT_THROW(o.Check(), InputError) << bad;
  }
  RayBatchOptions o;
  o.skinning_jacobian_cutoff = 0.0;
  EXPECT_NO_THROW(o.Check());
}

INSTANTIATE_TEST_SUITE_P(AllTerms, DeltaSkinningJacobian, ::testing::ValuesIn(RayTerms()),
                         [](const ::testing::TestParamInfo<LossTerm>& info) {
                           return std::string(LossTermName(info.param));
                         });

}  // namespace
}  // namespace banmo
