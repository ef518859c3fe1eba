// The loss table (losses/loss_table.h) is the one list of loss terms: these
// tests hold its rows consistent with the weights, the ray selection and the
// residual blocks derived from it.
#include "banmo/losses/loss_table.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "banmo/losses/ray.h"
#include "banmo/losses/ray_batch.h"
#include "common/test_scene.h"

namespace banmo {
namespace {

TEST(LossTable, KeysAreUniqueAndNamed) {
  std::set<std::string> keys;
  for (const LossTermInfo& info : kLossTable) {
    EXPECT_TRUE(keys.insert(info.key).second) << "duplicate key " << info.key;
    EXPECT_EQ(LossTermName(info.term), std::string(info.key));
    EXPECT_GT(info.residuals, 0) << info.key;
    EXPECT_GE(info.default_weight, 0.0) << info.key;
  }
}

TEST(LossTable, RayTermsReadBlocksRegularisersDoNot) {
  for (const LossTermInfo& info : kLossTable) {
    if (IsRayTerm(info.term)) {
      EXPECT_NE(info.blocks, 0u) << info.key;
      EXPECT_NE(info.rays, RaySelect::kNotPerRay) << info.key;
    } else {
      EXPECT_EQ(info.blocks, 0u) << info.key;
      EXPECT_EQ(info.rays, RaySelect::kNotPerRay) << info.key;
    }
  }
}

TEST(LossTable, DefaultWeightsComeFromTheTable) {
  const RayLossWeights weights;
  for (LossTerm term : RayTerms()) {
    EXPECT_EQ(weights[term], LossInfo(term).default_weight) << LossTermName(term);
  }
  const RayLossWeights only = RayLossWeights::Only({LossTerm::kSilhouette});
  for (LossTerm term : RayTerms()) {
    EXPECT_EQ(only[term], term == LossTerm::kSilhouette ? 1.0 : 0.0) << LossTermName(term);
  }
}

TEST(LossTable, ResidualCountsScaleWithSamplesOnlyWherePerSample) {
  for (LossTerm term : RayTerms()) {
    const int factor = LossInfo(term).per_sample ? 5 : 1;
    EXPECT_EQ(LossTermResiduals(term, 5), factor * LossInfo(term).residuals) << LossTermName(term);
  }
}

// The residual blocks of the test scene read exactly the table's blocks that
// the ray has, in RayBlock order.
TEST(LossTable, TermBlocksFollowTheTable) {
  TestSceneOptions options;
  options.delta_skinning = true;
  TestScene scene = MakeTestScene(options);
  const RayBatch& batch = *scene.batch;
  for (int r = 0; r < batch.num_rays(); ++r) {
    const RayParameters p = batch.ModelParameters(batch.rays()[r]);
    for (LossTerm term : RayTerms()) {
      if (!batch.rays()[r].HasTerm(term, batch.options().weights)) continue;
      int previous = -1;
      int count = 0;
      for (RayBlock b : batch.TermBlocks(r, term)) {
        EXPECT_TRUE(Contains(LossInfo(term).blocks, b)) << LossTermName(term);
        EXPECT_GT(static_cast<int>(b), previous);
        previous = b;
        ++count;
      }
      int expected = 0;
      for (int b = 0; b < kNumRayBlocks; ++b) {
        expected +=
            Contains(LossInfo(term).blocks, static_cast<RayBlock>(b)) && p.block[b] != nullptr;
      }
      EXPECT_EQ(count, expected) << LossTermName(term);
    }
  }
}

// An object pixel's ray with a feature and two samples.
Ray ObjectRayWithFeature() {
  Ray ray;
  ray.mask = 1.0;
  ray.has_feature = true;
  ray.samples.depths = {1.0, 2.0};
  ray.samples.deltas = {1.0, 1.0};
  return ray;
}

TEST(LossTable, ZeroWeightSwitchesATermOff) {
  Ray ray = ObjectRayWithFeature();
  RayLossWeights weights;
  EXPECT_TRUE(ray.HasTerm(LossTerm::kCycle2d, weights));
  weights[LossTerm::kCycle2d] = 0.0;
  EXPECT_FALSE(ray.HasTerm(LossTerm::kCycle2d, weights));
  EXPECT_FALSE(ray.HasTerm(LossTerm::kEikonal, weights));  // not a per-ray term
}

// feature_render is off by default (configs written before it keep their
// meaning) and, when weighted, applies to object pixels with a feature.
TEST(LossTable, FeatureRenderIsOptInOnObjectPixelsWithFeatures) {
  Ray ray = ObjectRayWithFeature();
  RayLossWeights weights;
  EXPECT_FALSE(ray.HasTerm(LossTerm::kFeatureRender, weights));
  weights[LossTerm::kFeatureRender] = 0.5;
  EXPECT_TRUE(ray.HasTerm(LossTerm::kFeatureRender, weights));
  ray.has_feature = false;
  EXPECT_FALSE(ray.HasTerm(LossTerm::kFeatureRender, weights));
  ray.has_feature = true;
  ray.mask = 0.0;
  EXPECT_FALSE(ray.HasTerm(LossTerm::kFeatureRender, weights));
}

}  // namespace
}  // namespace banmo
