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

// Residual rows 0..29 of rays 0 and 1: rgb (3), silhouette (1), flow (2),
// feature match (3), 2D cycle (2), rendered embedding (16), then the first
// 3D-cycle rows.
// Regenerated 2026-11-25: the root correction moved to the object side
// (G = G0 dG; the scene's frames have non-identity dG).
// Extended 2026-11-27: the feature_render rows (11..26) inserted; rows 0..10
// and the 3D-cycle rows (now 27..29) kept their values.
constexpr size_t kGoldenRows = 30;
const std::vector<std::vector<double>> kGolden = {
    {-6.513518040227e-01, -6.165748615525e-01, -3.133443316272e-01, -9.554848416457e-01,
     9.049399029701e-02,  -8.354966801812e-02, 2.073155048986e-01,  -2.765616233385e-01,
     -3.040321378715e-01, -2.108009154888e-02, -7.893113053827e-01, -7.731499707435e-01,
     1.152706511333e-01,  5.131040204400e-02,  -9.488999435498e-01, -8.778365201372e-01,
     -6.610702907519e-01, 9.291366933684e-01,  1.083857126596e+00,  -3.525825681112e-01,
     -9.001231602656e-01, -6.580624361817e-01, 1.145529432121e-01,  -3.977538155213e-01,
     7.899671075572e-01,  -6.409229900934e-01, 6.796738747477e-01,  2.950122817537e-04,
     -2.688011201476e-04, 5.810214995607e-04},
    {-1.862796736043e-01, -7.914707247803e-01, -6.355234506075e-01, -9.584258532850e-01,
     6.539098350762e-02,  1.173113651908e-02,  -2.508133768993e-01, -1.005634359706e-01,
     8.501740026156e-02,  4.399554270847e-04,  -6.505776964045e-01, 1.636082646914e-01,
     3.606065388024e-01,  -2.143439661974e-01, 2.274050908379e-01,  9.749677672445e-01,
     1.659583439050e-01,  -2.495285257072e-01, 1.692415039419e-01,  -1.734034577528e-01,
     -1.092738889979e-01, -7.338319239499e-02, 5.810859219006e-01,  -4.380595080271e-02,
     1.143569219283e+00,  -8.610049526663e-01, -4.284194804563e-01, 3.312538347602e-04,
     1.080887959437e-04,  2.661205319757e-04}};

TEST(RayResiduals, GoldenValuesOnTinyScene) {
  TestScene scene = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  batch.EvaluateAll(/*jacobians=*/false);
  if (std::getenv("BANMO_PRINT_GOLDEN") != nullptr) {
    std::printf("const std::vector<std::vector<double>> kGolden = {\n");
    for (int r = 0; r < 2; ++r) {
      std::printf("    {");
      for (size_t i = 0; i < kGoldenRows; ++i) {
        std::printf("%s%.12e", i ? ", " : "", batch.evaluation(r).residuals[i]);
      }
      std::printf("}%s\n", r ? "};" : ",");
    }
  }
  for (int r = 0; r < 2; ++r) {
    const RayEvaluation& ev = batch.evaluation(r);
    ASSERT_EQ(kGolden[r].size(), kGoldenRows);
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
