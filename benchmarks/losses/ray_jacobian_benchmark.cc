// Rays per second of Jacobian assembly (residuals + Jacobians of every loss
// term of a ray): the batched mixed-mode path (RayBatch, docs/design.md)
// against the full-Jet reference, at MLP width 16/32/64, 32 samples per ray,
// 8 bones, all losses on, positional encoding with 6 bands, 3 hidden SDF
// layers; second argument: delta skinning off/on (MLP_Delta of the same
// width, 1 hidden layer, non-zero output layer). BM_RayGradient_Batched is
// the first-order path Adam uses (RayBatch::EvaluateGradient: one cotangent
// row per ray, no Jacobian). BM_RayGradient_FeatureRender: the same with
// the rendered-embedding term on (weight 0.2, 16 rows per ray), second
// argument losses.feature_render_embedding_only off/on (problems/default.yaml
// ships it on), no delta skinning.
//
//   ./build/bin/ray_jacobian_benchmark --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <map>

#include "banmo/losses/ray_batch.h"
#include "banmo/losses/ray_reference.h"
#include "common/test_scene.h"

namespace banmo {
namespace {

TestSceneOptions BenchmarkScene(int width, int num_rays, bool delta_skinning) {
  TestSceneOptions o;
  o.delta_skinning = delta_skinning;
  o.mlp_width = width;
  o.sdf_layers = 3;
  o.num_bands = 6;
  o.appearance_dim = 4;
  o.num_bones = 8;
  o.num_rays = num_rays;
  o.num_samples = 32;
  o.grid_points = 1024;
  o.match_top_k = 16;
  // The terms of the recorded numbers (benchmarks/README.md): feature_render
  // (added 2026-11-27, 16 rows per ray) stays off so they remain comparable.
  o.weights[LossTerm::kFeatureRender] = 0.0;
  return o;
}

constexpr LossTerm kTerms[] = {LossTerm::kRgb,          LossTerm::kSilhouette, LossTerm::kFlow,
                               LossTerm::kFeatureMatch, LossTerm::kCycle2d,    LossTerm::kCycle3d};

void BM_RayJacobian_Batched(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  constexpr int kRays = 512;
  TestScene scene = MakeTestScene(BenchmarkScene(width, kRays, state.range(1) != 0));
  for (auto _ : state) {
    scene.batch->EvaluateAll(/*jacobians=*/true);
    benchmark::DoNotOptimize(scene.batch->evaluation(0).residuals.data());
  }
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(kRays) * state.iterations(),
                                                    benchmark::Counter::kIsRate);
  state.counters["weights"] = scene.model->sdf_size() + scene.model->color_size() +
                              scene.model->embedding_size() + scene.model->delta_skinning_size();
}

// The gradient path (RayBatch::EvaluateGradient) on `num_rays` rays.
void TimeGradient(benchmark::State& state, const TestSceneOptions& options, int num_rays) {
  TestScene scene = MakeTestScene(options);
  const RayRobustLosses robust{};
  for (auto _ : state) {
    std::map<const double*, Eigen::VectorXd> gradient;
    benchmark::DoNotOptimize(scene.batch->EvaluateGradient(robust, &gradient));
  }
  state.counters["rays_per_s"] = benchmark::Counter(
      static_cast<double>(num_rays) * state.iterations(), benchmark::Counter::kIsRate);
}

void BM_RayGradient_Batched(benchmark::State& state) {
  constexpr int kRays = 512;
  TimeGradient(state, BenchmarkScene(static_cast<int>(state.range(0)), kRays, state.range(1) != 0),
               kRays);
}

void BM_RayGradient_FeatureRender(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  constexpr int kRays = 512;
  TestSceneOptions o = BenchmarkScene(width, kRays, /*delta_skinning=*/false);
  o.weights[LossTerm::kFeatureRender] = 0.2;
  o.feature_render_embedding_only = state.range(1) != 0;
  TimeGradient(state, o, kRays);
}

void BM_RayJacobian_FullJet(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  TestScene scene = MakeTestScene(BenchmarkScene(width, 1, state.range(1) != 0));
  RayBatch& batch = *scene.batch;
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  std::vector<std::vector<double*>> params;
  for (LossTerm term : kTerms) {
    costs.push_back(MakeReferenceCostFunction(batch, 0, term));
    params.push_back(batch.TermParameterBlocks(0, term));
  }
  std::vector<std::vector<double>> residuals(costs.size()), jac_storage;
  for (auto _ : state) {
    for (size_t t = 0; t < costs.size(); ++t) {
      const ceres::CostFunction& c = *costs[t];
      residuals[t].resize(c.num_residuals());
      std::vector<std::vector<double>> jac(c.parameter_block_sizes().size());
      std::vector<double*> jac_ptr(jac.size());
      for (size_t b = 0; b < jac.size(); ++b) {
        jac[b].resize(c.num_residuals() * c.parameter_block_sizes()[b]);
        jac_ptr[b] = jac[b].data();
      }
      c.Evaluate(params[t].data(), residuals[t].data(), jac_ptr.data());
      benchmark::DoNotOptimize(jac_ptr.data());
    }
  }
  state.counters["rays_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

BENCHMARK(BM_RayJacobian_Batched)
    ->ArgsProduct({{16, 32, 64}, {0, 1}})
    ->ArgNames({"width", "delta"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_RayGradient_Batched)
    ->ArgsProduct({{16, 32, 64}, {0, 1}})
    ->ArgNames({"width", "delta"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_RayGradient_FeatureRender)
    ->ArgsProduct({{16, 32, 64}, {0, 1}})
    ->ArgNames({"width", "embedding_only"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_RayJacobian_FullJet)
    ->ArgsProduct({{16, 32, 64}, {0, 1}})
    ->ArgNames({"width", "delta"})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2)
    ->UseRealTime();

}  // namespace
}  // namespace banmo

BENCHMARK_MAIN();
