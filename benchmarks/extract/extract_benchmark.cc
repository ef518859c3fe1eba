// Extraction timings: marching cubes of the model's SDF MLP (width 64,
// 3 hidden layers, 6 encoding bands: the default ModelOptions) at the
// resolutions used by the solver's bounds refresh (48) and for meshes (128,
// 256), and the marching cubes alone on an analytic SDF (its overhead without
// the MLP).
#include <benchmark/benchmark.h>

#include <memory>

#include "banmo/extract/extract.h"
#include "banmo/util/parallel.h"

namespace banmo {
namespace {

std::unique_ptr<Model> DefaultModel() {
  ModelOptions options;  // sdf_width 64, sdf_layers 3, 6 bands, 8 bones
  PinholeCamera camera;
  camera.width = camera.height = 64;
  return std::make_unique<Model>(options, std::vector<int>{10}, std::vector<PinholeCamera>{camera});
}

// range(0): resolution; range(1): coarse_stride (1 = dense sampling).
void BM_ExtractCanonicalMesh_Mlp64(benchmark::State& state) {
  const auto model = DefaultModel();
  ExtractOptions options;
  options.grid.resolution = static_cast<int>(state.range(0));
  options.grid.coarse_stride = static_cast<int>(state.range(1));
  int faces = 0;
  MarchingCubesStats stats;
  for (auto _ : state) {
    const TriangleMesh mesh = ExtractCanonicalMesh(*model, options, &stats);
    faces = mesh.NumFaces();
  }
  state.counters["faces"] = faces;
  state.counters["threads"] = NumThreads();
  state.counters["evaluated_fraction"] =
      static_cast<double>(stats.num_evaluated) / static_cast<double>(stats.num_nodes);
  state.counters["sdf_points_per_s"] = benchmark::Counter(
      static_cast<double>(stats.num_evaluated) * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ExtractCanonicalMesh_Mlp64)
    ->Args({48, 4})
    ->Args({128, 4})
    ->Args({256, 4})
    ->Args({128, 1})
    ->Args({256, 1})
    ->ArgNames({"res", "stride"})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

void BM_SurfaceBounds_Mlp64(benchmark::State& state) {
  const auto model = DefaultModel();
  const Eigen::AlignedBox3d box(Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1));
  for (auto _ : state) benchmark::DoNotOptimize(SurfaceBounds(*model, box, 48));
}
BENCHMARK(BM_SurfaceBounds_Mlp64)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MarchingCubes_AnalyticSphere(benchmark::State& state) {
  GridOptions grid;
  grid.resolution = static_cast<int>(state.range(0));
  auto sphere = [](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
    *f = x.colwise().norm().transpose().array() - 0.5;
  };
  int faces = 0;
  for (auto _ : state) faces = MarchingCubes(sphere, grid).NumFaces();
  state.counters["faces"] = faces;
}
BENCHMARK(BM_MarchingCubes_AnalyticSphere)
    ->Arg(128)
    ->Arg(256)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_ArticulateMesh_Bones8(benchmark::State& state) {
  const auto model = DefaultModel();
  ExtractOptions options;
  options.grid.resolution = 128;
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options);
  for (auto _ : state) benchmark::DoNotOptimize(ArticulateMesh(*model, canonical, 0, 3));
  state.counters["vertices"] = canonical.NumVertices();
}
BENCHMARK(BM_ArticulateMesh_Bones8)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace banmo

BENCHMARK_MAIN();
