// Numerical stability of every ray term on hard inputs: residuals and
// Jacobians must be finite (a non-finite value is a bug, not a case to skip),
// and where the inputs are extreme but smooth the mixed-mode Jacobian still
// equals the full-Jet reference.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "banmo/deform/bones.h"
#include "banmo/losses/ray_batch.h"
#include "banmo/losses/ray_reference.h"
#include "common/test_scene.h"
#include "jacobian_test_util.h"

namespace banmo {
namespace {

using testing::AllFinite;
using testing::EvaluateCost;

constexpr std::array<LossTerm, kNumRayTerms> kTerms = RayTerms();

// Builds the tiny scene, applies `edit` to the model and rays, and checks
// every term of every ray through the batched path (and optionally against
// the reference).
void CheckScene(const TestSceneOptions& options, const std::function<void(TestScene*)>& edit,
                bool compare_reference, double reference_tolerance = 1e-9) {
  TestScene scene = MakeTestScene(options);
  if (edit) edit(&scene);
  RayBatch& batch = *scene.batch;
  batch.EvaluateAll(true);
  for (int r = 0; r < batch.num_rays(); ++r) {
    for (LossTerm term : kTerms) {
      if (!batch.rays()[r].HasTerm(term, batch.options().weights)) continue;
      auto cost = batch.MakeCostFunction(r, term);
      const auto params = batch.TermParameterBlocks(r, term);
      const auto e = EvaluateCost(*cost, params);
      ASSERT_TRUE(e.ok);
      EXPECT_TRUE(AllFinite(e)) << "ray " << r << " term " << LossTermName(term);
      if (compare_reference) {
        auto reference = MakeReferenceCostFunction(batch, r, term);
        const auto ref = EvaluateCost(*reference, params);
        if (testing::MaxAbs(ref) < 1e-9) {
          // A flat term (e.g. the silhouette behind a step-like density at
          // beta = 1e-4, or the 3D cycle with B <= 1 bones, where the warps
          // are exact inverses): both Jacobians are rounding noise.
          EXPECT_LT(testing::MaxAbs(e), 1e-9) << "ray " << r << " term " << LossTermName(term);
          if (term == LossTerm::kCycle3d && batch.model().num_bones() <= 1) {
            EXPECT_LT(e.residuals.cwiseAbs().maxCoeff(), 1e-9);
          }
        } else {
          EXPECT_LT(testing::RelativeJacobianError(e, ref), reference_tolerance)
              << "ray " << r << " term " << LossTermName(term);
        }
      }
    }
  }
}

// Rebuilds the rays (after editing them) so per-minibatch constants are
// recomputed.
void EditRays(TestScene* scene, const std::function<void(Ray*)>& edit) {
  std::vector<Ray> rays = scene->batch->rays();
  for (Ray& ray : rays) {
    edit(&ray);
    ray.match_indices.clear();
    ray.cycle_tau.clear();
  }
  scene->batch->SetRays(std::move(rays));
}

TEST(HardCases, TinyBeta) {
  CheckScene(
      TestSceneOptions(), [](TestScene* s) { *s->model->log_beta() = std::log(1e-4); }, true);
}

TEST(HardCases, HugeBeta) {
  CheckScene(
      TestSceneOptions(), [](TestScene* s) { *s->model->log_beta() = std::log(1e3); }, true);
}

TEST(HardCases, TinyAndHugeBoneScales) {
  for (double scale : {1e-4, 1e3}) {
    CheckScene(
        TestSceneOptions(),
        [scale](TestScene* s) {
          for (int b = 0; b < s->model->num_bones(); ++b) {
            for (int k = 0; k < 3; ++k) {
              s->model->bones()[kBoneSize * b + kBoneLogScale + k] = std::log(scale);
            }
          }
          EditRays(s, [](Ray*) {});
        },
        false);
  }
}

TEST(HardCases, OneBoneAndSixtyFourBones) {
  for (int bones : {1, 64}) {
    TestSceneOptions o;
    o.num_bones = bones;
    o.num_rays = 2;
    CheckScene(o, nullptr, bones == 1);
  }
}

TEST(HardCases, RigidObjectWithoutBones) {
  TestSceneOptions o;
  o.num_bones = 0;
  CheckScene(o, nullptr, true);
}

TEST(HardCases, SamplesBehindTheCamera) {
  CheckScene(
      TestSceneOptions(),
      [](TestScene* s) {
        EditRays(s, [](Ray* ray) {
          std::mt19937 rng(1);
          ray->samples = StratifiedSamples(8, -2.0, 3.5, 1.0, true, &rng);
        });
      },
      false);
}

TEST(HardCases, ZeroNormFeatures) {
  CheckScene(
      TestSceneOptions(),
      [](TestScene* s) { EditRays(s, [](Ray* ray) { ray->feature.setZero(); }); }, true);
}

TEST(HardCases, ThousandPixelFlow) {
  CheckScene(
      TestSceneOptions(),
      [](TestScene* s) {
        EditRays(s, [](Ray* ray) { ray->flow = Eigen::Vector2d(1000.0, -1000.0); });
      },
      true);
}

TEST(HardCases, SkinningLogitsOfTenThousand) {
  // Bone scale 0.005 at distance ~0.5: |logit| = d^2 / (2 s^2) ~ 5e3..1e4.
  CheckScene(
      TestSceneOptions(),
      [](TestScene* s) {
        for (int b = 0; b < s->model->num_bones(); ++b) {
          for (int k = 0; k < 3; ++k) {
            s->model->bones()[kBoneSize * b + kBoneLogScale + k] = std::log(0.005);
          }
        }
        EditRays(s, [](Ray*) {});
      },
      false);
  // And the blend itself with logits of +-1e4.
  const double logits[3] = {1e4, -1e4, 1e4 - 1.0};
  const double points[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  double out[3];
  BlendPoints(3, logits, points, out);
  EXPECT_TRUE(std::isfinite(out[0]) && std::isfinite(out[1]) && std::isfinite(out[2]));
  EXPECT_NEAR(out[0], 1.0 / (1.0 + std::exp(-1.0)), 1e-12);
}

}  // namespace
}  // namespace banmo
