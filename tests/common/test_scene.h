// A small, fixed-seed synthetic ray batch for the residual-level regression
// tests and the Jacobian-assembly benchmark: a model with random (but
// deterministic) poses, bones and MLP weights, and rays through the object
// that exercise every loss term. Test-only: target banmo_test_common
// (tests/common/CMakeLists.txt), linked by tests and benchmarks alone.
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "banmo/losses/ray_batch.h"
#include "banmo/model/model.h"

namespace banmo {

// rgb 1, silhouette 1, flow 0.01, feature_match 1, cycle_2d 0.01, feature_render 1,
// cycle_3d 1.
RayLossWeights GoldenRayLossWeights();

struct TestSceneOptions {
  int mlp_width = 8;       // hidden width of all MLPs
  int sdf_layers = 2;      // hidden layers of the SDF MLP
  int num_bands = 2;       // positional-encoding bands
  int appearance_dim = 2;  // appearance code size
  int num_bones = 3;       // B
  int num_rays = 4;
  int num_samples = 8;        // N per ray
  int grid_points = 64;       // soft-argmax grid size M
  int match_top_k = 8;        // K
  double perturbation = 0.2;  // size of the random pose/bone perturbations
  // Delta skinning (Eq. 14): a small MLP_Delta (width mlp_width, 1 hidden
  // layer, 1 band, 3-d pose codes) with a random, non-zero output layer so
  // every derivative of the delta path is exercised.
  bool delta_skinning = false;
  double silhouette_weight = 1.0;  // every ray's Ray::silhouette_weight
  DensityModel density = DensityModel::kVolSdf;
  // RayBatchOptions::skinning_jacobian_cutoff: 0 (exact) so the Jacobians
  // equal the full-Jet reference to rounding.
  double skinning_jacobian_cutoff = 0.0;
  bool feature_render_embedding_only = false;  // RayBatchOptions'
  bool hold_cycle_tau = true;                  // RayBatchOptions'
  uint32_t seed = 7;
  // The weights the golden values were generated with (not the config's
  // defaults): rgb, silhouette, flow, feature_match, cycle_2d, feature_render,
  // cycle_3d.
  // (Built out of line: GCC 12 reports the inlined std::array temporary of
  // an in-class initialiser as uninitialised, -Wuninitialized.)
  RayLossWeights weights = GoldenRayLossWeights();
};

struct TestScene {
  std::unique_ptr<Model> model;
  std::unique_ptr<RayBatch> batch;
};

// Two frames of one 64 x 64 video, object about 3 units from the camera;
// every ray is an object pixel with flow to the other frame and a feature.
TestScene MakeTestScene(const TestSceneOptions& options);

// Samples of a batch on each side of kMinWarpTau (losses/sample_weight.h).
struct SampleWeightSplit {
  int skipped = 0;  // tau < kMinWarpTau: no colour, flow or 3D cycle
  int counted = 0;  // tau >= kMinWarpTau
};

// The test rays' samples lie 0.67-0.9 outside the random surface, so at the
// scene's beta every sample counts. Sets log beta to the first of 0.1, 0.09,
// 0.08, 0.07, 0.06 that leaves at least `min_each` samples on each side of
// kMinWarpTau, counting the samples of the rays with `term` (every ray if
// none), and returns that split (the last beta's if none does). The batch is
// left evaluated without Jacobians at that beta. Needs hold_cycle_tau off for
// the 3D cycle's weights to follow.
SampleWeightSplit SharpenDensityUntilSomeSamplesSkip(TestScene& scene,
                                                     std::optional<LossTerm> term = std::nullopt,
                                                     int min_each = 4);

}  // namespace banmo
