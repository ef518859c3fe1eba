// Evaluation speed on 10k-vertex meshes: nearest neighbours with the FLANN
// kd-tree against brute force, one Chamfer frame, and full protocol frames.
// items_per_second = frames per second (queries per second for BM_Nearest_*),
// measured in wall-clock time (the searches run on NumThreads() threads).
#include <benchmark/benchmark.h>

#include "../../tests/eval/test_shapes.h"
#include "banmo/eval/evaluate.h"
#include "banmo/eval/metrics.h"
#include "banmo/geometry/nearest_neighbors.h"

namespace banmo {
namespace {

// 2 + 100 * 100 = 10002 vertices each.
const TriangleMesh& Gt() {
  static const TriangleMesh mesh = testing::Blob(Eigen::Vector3d(0, 0, 3), 101, 100);
  return mesh;
}
const TriangleMesh& Pred() {
  static const TriangleMesh mesh =
      testing::Transformed(Gt(), 1.02, testing::Rotation(4.0, Eigen::Vector3d(0, 1, 1)),
                           Eigen::Vector3d(0.02, 0.0, 0.05));
  return mesh;
}

void BM_Nearest_KdTree(benchmark::State& state) {
  Eigen::VectorXi idx;
  Eigen::VectorXd sq;
  for (auto _ : state) {
    const KdTree3 tree(Gt().vertices);  // build included
    tree.Nearest(Pred().vertices, &idx, &sq);
    benchmark::DoNotOptimize(sq.data());
  }
  state.SetItemsProcessed(state.iterations() * Pred().NumVertices());
}
BENCHMARK(BM_Nearest_KdTree)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Nearest_BruteForce(benchmark::State& state) {
  Eigen::VectorXi idx;
  Eigen::VectorXd sq;
  for (auto _ : state) {
    BruteForceNearest(Gt().vertices, Pred().vertices, &idx, &sq);
    benchmark::DoNotOptimize(sq.data());
  }
  state.SetItemsProcessed(state.iterations() * Pred().NumVertices());
}
BENCHMARK(BM_Nearest_BruteForce)->Unit(benchmark::kMillisecond)->UseRealTime();

// One frame's Chamfer distance and F-score (both directions, no ICP).
void BM_ChamferFrame_KdTree(benchmark::State& state) {
  Eigen::VectorXi idx;
  Eigen::VectorXd a, b;
  for (auto _ : state) {
    const KdTree3 gt_tree(Gt().vertices);
    const KdTree3 pred_tree(Pred().vertices);
    gt_tree.Nearest(Pred().vertices, &idx, &a);
    pred_tree.Nearest(Gt().vertices, &idx, &b);
    benchmark::DoNotOptimize(ComputeDistanceMetrics(a.cwiseSqrt(), b.cwiseSqrt(), 2.0));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ChamferFrame_KdTree)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ChamferFrame_BruteForce(benchmark::State& state) {
  Eigen::VectorXi idx;
  Eigen::VectorXd a, b;
  for (auto _ : state) {
    BruteForceNearest(Gt().vertices, Pred().vertices, &idx, &a);
    BruteForceNearest(Pred().vertices, Gt().vertices, &idx, &b);
    benchmark::DoNotOptimize(ComputeDistanceMetrics(a.cwiseSqrt(), b.cwiseSqrt(), 2.0));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ChamferFrame_BruteForce)->Unit(benchmark::kMillisecond)->UseRealTime();

// Full protocol frames (kd-tree): scaling, ICP (up to 100 iterations), metrics.
void BM_EvaluatePair_Banmo(benchmark::State& state) {
  EvalOptions options;
  options.protocol = EvalProtocol::kBanmo;
  options.gt_mode = GtMode::kVertices;  // the vertex protocol (README); dense: eval_frame_benchmark
  int iterations = 0;
  for (auto _ : state) iterations = EvaluatePair(Pred(), Gt(), options).icp.iterations;
  state.SetItemsProcessed(state.iterations());
  state.counters["icp_iterations"] = iterations;
}
BENCHMARK(BM_EvaluatePair_Banmo)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_EvaluatePair_Surface(benchmark::State& state) {
  EvalOptions options;
  options.protocol = EvalProtocol::kSurface;  // 100000 samples, 10000 ICP queries per direction
  int iterations = 0;
  for (auto _ : state) iterations = EvaluatePair(Pred(), Gt(), options).icp.iterations;
  state.SetItemsProcessed(state.iterations());
  state.counters["icp_iterations"] = iterations;
}
BENCHMARK(BM_EvaluatePair_Surface)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace banmo

BENCHMARK_MAIN();
