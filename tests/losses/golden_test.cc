// Golden residual values on the fixed-seed tiny scene (tests/common/test_scene.h):
// any silent change of a formula, a layout or an initialisation fails here.
// If a change is intended, regenerate the values and say so in the commit.
#include <gtest/gtest.h>

#include <vector>

#include "banmo/losses/ray_batch.h"
#include "common/test_scene.h"

namespace banmo {
namespace {

// Residual rows 0..13 of rays 0 and 1: rgb (3), silhouette (1), flow (2),
// feature match (3), 2D cycle (2), then the first 3D-cycle rows.
const std::vector<std::vector<double>> kGolden = {
    {-6.572119536875e-01, -6.220705059966e-01, -3.188854851606e-01, -9.666721707701e-01,
     5.548918158865e-02, 1.828028108621e-02, 2.080733936110e-01, -2.910097339967e-01,
     -3.084905525732e-01, -5.787545099374e-02, -2.134958271860e+00, 1.236683130414e-04,
     -2.308663835593e-04, 3.004211308832e-04},
    {-1.879357017973e-01, -7.926151965790e-01, -6.370998141464e-01, -9.610108827997e-01,
     1.107655577702e-01, -9.178370049489e-02, -2.674110100439e-01, -8.035275736944e-02,
     8.662074570010e-02, -1.040370995592e+00, 7.718489307564e-01, 6.143917051011e-05,
     2.727552767792e-05, 1.193184874673e-04}};

TEST(RayResiduals, GoldenValuesOnTinyScene) {
  TestScene scene = MakeTestScene(TestSceneOptions());
  RayBatch& batch = *scene.batch;
  batch.EvaluateAll(/*jacobians=*/false);
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
