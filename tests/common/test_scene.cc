#include "common/test_scene.h"

#include <cmath>
#include <random>

#include "banmo/deform/bones.h"
#include "banmo/geometry/se3.h"
#include "banmo/losses/sample_weight.h"
#include "banmo/volume/ray_samples.h"

namespace banmo {

RayLossWeights GoldenRayLossWeights() {
  return RayLossWeights({1.0, 1.0, 0.01, 1.0, 0.01, 1.0, 1.0});
}

TestScene MakeTestScene(const TestSceneOptions& o) {
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  ModelOptions mo;
  mo.field.position_encoding.num_bands = o.num_bands;
  mo.field.sdf_width = o.mlp_width;
  mo.field.sdf_layers = o.sdf_layers;
  mo.field.color_width = o.mlp_width;
  mo.field.color_layers = 1;
  mo.field.embedding_width = o.mlp_width;
  mo.field.embedding_layers = 1;
  mo.field.appearance_code_dim = o.appearance_dim;
  mo.num_bones = o.num_bones;
  mo.init_bone_scale = 0.3;
  // A small sphere and a soft density so the rays are neither empty nor
  // saturated (opacity well inside (0, 1)): every derivative is exercised.
  mo.field.init_sphere_radius = 0.3;
  mo.init_beta = 0.15;
  mo.density = o.density;
  mo.seed = o.seed;
  if (o.delta_skinning) {
    mo.delta_skinning.enabled = true;
    mo.delta_skinning.width = o.mlp_width;
    mo.delta_skinning.hidden_layers = 1;
    mo.delta_skinning.num_bands = 1;
    mo.delta_skinning.pose_code_dim = 3;
    mo.delta_skinning.code_init_std = 0.5;
  }
  PinholeCamera camera;
  camera.width = camera.height = 64;
  camera.intrinsics << 80.0, 82.0, 32.0, 31.0;
  TestScene scene;
  scene.model =
      std::make_unique<Model>(mo, std::vector<int>{2}, std::vector<PinholeCamera>{camera});
  Model& m = *scene.model;
  const double p = o.perturbation;
  for (int t = 0; t < 2; ++t) {
    FrameParameters& f = m.frame(0, t);
    f.root_init = PoseFromAngleAxis(Eigen::Vector3d(0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng)),
                                    Eigen::Vector3d(0.05 * u(rng), 0.05 * u(rng), 3.0));
    f.root_delta = PoseFromAngleAxis(p * Eigen::Vector3d(u(rng), u(rng), u(rng)),
                                     0.1 * p * Eigen::Vector3d(u(rng), u(rng), u(rng)));
    for (int b = 0; b < o.num_bones; ++b) {
      const Pose j = PoseFromAngleAxis(p * Eigen::Vector3d(u(rng), u(rng), u(rng)),
                                       0.2 * p * Eigen::Vector3d(u(rng), u(rng), u(rng)));
      std::copy(j.data(), j.data() + kPoseSize, f.bones_t.data() + kPoseSize * b);
    }
  }
  for (int b = 0; b < o.num_bones; ++b) {
    double* bone = m.bones() + kBoneSize * b;
    for (int k = 0; k < 3; ++k) bone[kBoneCenter + k] += 0.1 * u(rng);
    const Pose q =
        PoseFromAngleAxis(Eigen::Vector3d(u(rng), u(rng), u(rng)), Eigen::Vector3d::Zero());
    std::copy(q.data(), q.data() + 4, bone + kBoneQw);
    for (int k = 0; k < 3; ++k) bone[kBoneLogScale + k] += 0.3 * u(rng);
  }
  for (double& a : m.video(0).appearance) a = 0.5 * u(rng);
  if (m.has_delta_skinning()) {
    // Output layer random: delta logits of order 1 (the Gaussian logits here
    // are of order 1 too), so both components shape the weights.
    const Mlp& mlp = m.delta_skinning()->mlp();
    const int last = mlp.NumLinearLayers() - 1;
    for (int k = mlp.WeightOffset(last); k < mlp.NumParameters(); ++k) {
      m.delta_skinning_params()[k] = 0.8 * u(rng);
    }
  }
  *m.log_beta() += 0.2 * u(rng);

  RayBatchOptions bo;
  bo.weights = o.weights;
  bo.match_top_k = o.match_top_k;
  bo.matcher.exact = true;
  bo.skinning_jacobian_cutoff = o.skinning_jacobian_cutoff;
  bo.feature_render_embedding_only = o.feature_render_embedding_only;
  bo.hold_cycle_tau = o.hold_cycle_tau;
  scene.batch = std::make_unique<RayBatch>(&m, bo);
  Eigen::Matrix3Xd grid(3, o.grid_points);
  for (int i = 0; i < o.grid_points; ++i)
    grid.col(i) = 0.6 * Eigen::Vector3d(u(rng), u(rng), u(rng));
  scene.batch->SetMatchGrid(grid);

  std::vector<Ray> rays(o.num_rays);
  for (int r = 0; r < o.num_rays; ++r) {
    Ray& ray = rays[r];
    ray.video = 0;
    ray.frame = r % 2;
    ray.partner_frame = 1 - ray.frame;
    ray.uv = Eigen::Vector2d(32.0 + 8.0 * u(rng), 31.0 + 8.0 * u(rng));
    ray.rgb = Eigen::Vector3d(0.5 + 0.4 * u(rng), 0.5 + 0.4 * u(rng), 0.5 + 0.4 * u(rng));
    ray.mask = 1.0;
    ray.silhouette_weight = o.silhouette_weight;
    ray.has_flow = true;
    ray.flow = Eigen::Vector2d(2.0 * u(rng), 2.0 * u(rng));
    ray.has_feature = true;
    for (int c = 0; c < 16; ++c) ray.feature[c] = u(rng);
    ray.samples = StratifiedSamples(o.num_samples, 2.2, 3.8,
                                    RayDirectionLength(camera.intrinsics, ray.uv), true, &rng);
  }
  scene.batch->SetRays(std::move(rays));
  return scene;
}

SampleWeightSplit SharpenDensityUntilSomeSamplesSkip(TestScene& scene, std::optional<LossTerm> term,
                                                     int min_each) {
  RayBatch& batch = *scene.batch;
  SampleWeightSplit split;
  for (double beta : {0.1, 0.09, 0.08, 0.07, 0.06}) {
    *scene.model->log_beta() = std::log(beta);
    batch.Invalidate();
    batch.EvaluateAll(/*jacobians=*/false);
    split = SampleWeightSplit();
    for (int r = 0; r < batch.num_rays(); ++r) {
      if (term && !batch.rays()[r].HasTerm(*term, batch.options().weights)) continue;
      for (double tau : batch.evaluation(r).tau)
        ++(WarpsSample(tau) ? split.counted : split.skipped);
    }
    if (split.skipped >= min_each && split.counted >= min_each) break;
  }
  return split;
}

}  // namespace banmo
