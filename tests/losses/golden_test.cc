// Golden residual values on the fixed-seed tiny scene (tests/common/test_scene.h):
// any silent change of a formula, a layout or an initialisation fails here.
// If a change is intended, regenerate the values and say so in the commit:
//   BANMO_PRINT_GOLDEN=1 build/tests/losses/losses_test --gtest_filter='RayResiduals.Golden*'
// prints kGolden as C++ to paste here.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <vector>

#include "banmo/losses/ray_batch.h"
#include "common/test_scene.h"

namespace banmo {
namespace {

// Residual rows 0..13 of rays 0 and 1: rgb (3), silhouette (1), flow (2),
// feature match (3), 2D cycle (2), then the first 3D-cycle rows.
// Regenerated 2026-11-25: the root correction moved to the object side
// (G = G0 dG; the scene's frames have non-identity dG).
const std::vector<std::vector<double>> kGolden = {
    {-6.513518040227e-01, -6.165748615525e-01, -3.133443316272e-01, -9.554848416457e-01,
     9.049399029701e-02, -8.354966801812e-02, 2.073155048986e-01, -2.765616233385e-01,
     -3.040321378715e-01, -2.108009154888e-02, -7.893113053827e-01, 2.950122817537e-04,
     -2.688011201476e-04, 5.810214995607e-04},
    {-1.862796736043e-01, -7.914707247803e-01, -6.355234506075e-01, -9.584258532850e-01,
     6.539098350762e-02, 1.173113651908e-02, -2.508133768993e-01, -1.005634359706e-01,
     8.501740026156e-02, 4.399554270847e-04, -6.505776964045e-01, 3.312538347602e-04,
     1.080887959437e-04, 2.661205319757e-04}};

TEST(RayResiduals, GoldenValuesOnTinyScene) {
  TestScene scene = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  batch.EvaluateAll(/*jacobians=*/false);
  if (std::getenv("BANMO_PRINT_GOLDEN") != nullptr) {
    std::printf("const std::vector<std::vector<double>> kGolden = {\n");
    for (int r = 0; r < 2; ++r) {
      std::printf("    {");
      for (size_t i = 0; i < kGolden[r].size(); ++i) {
        std::printf("%s%.12e", i ? ", " : "", batch.evaluation(r).residuals[i]);
      }
      std::printf("}%s\n", r ? "};" : ",");
    }
  }
  for (int r = 0; r < 2; ++r) {
    const RayEvaluation& ev = batch.evaluation(r);
    ASSERT_GE(ev.residuals.size(), kGolden[r].size());
    for (size_t i = 0; i < kGolden[r].size(); ++i) {
      // 13 significant digits stored; 1e-10 relative allows for libm's last
      // bits across machines, far below any formula change.
      EXPECT_NEAR(ev.residuals[i], kGolden[r][i], 1e-10 * std::max(1e-3, std::abs(kGolden[r][i])))
          << "ray " << r << " row " << i;
    }
  }
}

}  // namespace
}  // namespace banmo
