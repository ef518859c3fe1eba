// Seconds per evaluated frame against the ground truth (issue 19: at most
// 1 s per frame on 2 cores, whatever the model), for the dense ground truth
// (the default), BANMo's raw vertices and the previous dense protocol
// (--gt-mode vertices --gt-max-edge 0.02). benchmarks/eval/README.md has the
// command and the measured numbers.
//
// Scenes (camera coordinates, from the synth library):
// - Fox: frame 0 of the glTF Fox (Walk), 1,728 vertices, 576 triangles.
// - Fox36k: the same frame with the 40 % of its triangles furthest along x
//   split 4 times (256 triangles each): about 36k vertices with long and
//   short edges mixed, like the 34k-vertex humanoid of issue 19.
// The prediction of each: its ground truth split into triangles no longer
// than 0.4 % of the bounding-box diagonal (about 100k vertices, like a
// marching-cubes mesh at 256), moved by a smooth wave of amplitude 2 % of
// the diagonal, rotated by 3 degrees about the viewing axis through the
// centre and shifted by 0.5 % of the diagonal.
// Counters: chamfer_cm, F@1/F@2 (percent), icp_iterations, the median-depth
// scale applied to the prediction (the prediction has the GT's scale, so 1 is
// right), pred/gt_points (the points averaged), and cpu_s, the
// process CPU seconds per frame (all threads; the wall time is the "Time"
// column).
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <ctime>
#include <string>
#include <vector>

#include "banmo/eval/evaluate.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"

namespace banmo {
namespace {

const TriangleMesh& FoxFrame() {
  static const TriangleMesh mesh = [] {
    const synth::Rig rig = synth::LoadRig(std::string(BANMO_SHARED_DIR) + "/data/gltf/Fox/Fox.glb");
    synth::SynthOptions options;
    options.num_videos = 1;
    options.frames_per_video = 2;
    options.image_size = 16;
    options.flow_gaps = {1};
    return synth::RenderSyntheticScene(rig, options).gt_meshes[0][0];
  }();
  return mesh;
}

// Every triangle of `faces` split into n^2 (n per triangle), vertices of a
// triangle not shared with its neighbours (the Fox is a triangle soup).
TriangleMesh SplitTriangles(const TriangleMesh& mesh, const std::vector<int>& n_of_face) {
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector3i> f;
  for (int t = 0; t < mesh.NumFaces(); ++t) {
    const int n = n_of_face[static_cast<std::size_t>(t)];
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, t));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, t));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, t));
    std::vector<int> id(static_cast<std::size_t>((n + 1) * (n + 1)), -1);
    auto at = [&](int i, int j) -> int& { return id[static_cast<std::size_t>(i * (n + 1) + j)]; };
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        at(i, j) = static_cast<int>(v.size());
        v.push_back(a + (static_cast<double>(i) / n) * (b - a) +
                    (static_cast<double>(j) / n) * (c - a));
      }
    }
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        f.emplace_back(at(i, j), at(i + 1, j), at(i, j + 1));
        if (i + j + 1 < n) f.emplace_back(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
      }
    }
  }
  TriangleMesh out;
  out.vertices.resize(3, static_cast<Eigen::Index>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) out.vertices.col(static_cast<Eigen::Index>(i)) = v[i];
  out.faces.resize(3, static_cast<Eigen::Index>(f.size()));
  for (std::size_t i = 0; i < f.size(); ++i) out.faces.col(static_cast<Eigen::Index>(i)) = f[i];
  return out;
}

double Diagonal(const TriangleMesh& mesh) {
  return (mesh.vertices.rowwise().maxCoeff() - mesh.vertices.rowwise().minCoeff()).norm();
}

const TriangleMesh& Fox36k() {
  static const TriangleMesh mesh = [] {
    const TriangleMesh& fox = FoxFrame();
    std::vector<double> x;
    for (int t = 0; t < fox.NumFaces(); ++t) x.push_back(fox.vertices.col(fox.faces(0, t)).x());
    std::vector<double> sorted = x;
    std::sort(sorted.begin(), sorted.end());
    const double cut = sorted[static_cast<std::size_t>(0.6 * static_cast<double>(sorted.size()))];
    std::vector<int> n;
    for (double xi : x) n.push_back(xi > cut ? 16 : 1);
    return SplitTriangles(fox, n);
  }();
  return mesh;
}

TriangleMesh Prediction(const TriangleMesh& gt) {
  const double diagonal = Diagonal(gt);
  std::vector<int> n;
  for (int t = 0; t < gt.NumFaces(); ++t) {
    double longest = 0.0;
    for (int k = 0; k < 3; ++k) {
      longest = std::max(
          longest,
          (gt.vertices.col(gt.faces(k, t)) - gt.vertices.col(gt.faces((k + 1) % 3, t))).norm());
    }
    n.push_back(std::max(1, static_cast<int>(std::ceil(longest / (0.004 * diagonal)))));
  }
  TriangleMesh pred = SplitTriangles(gt, n);
  const Eigen::Vector3d center =
      0.5 * (gt.vertices.rowwise().maxCoeff() + gt.vertices.rowwise().minCoeff());
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (int i = 0; i < pred.NumVertices(); ++i) {
    const Eigen::Vector3d u = (pred.vertices.col(i) - center) / diagonal;
    const double wave = 0.02 * diagonal * std::sin(25.0 * u.x()) * std::cos(19.0 * u.y());
    const Eigen::Vector3d moved = pred.vertices.col(i) + wave * Eigen::Vector3d(1.0, 0.5, 0.0);
    pred.vertices.col(i) =
        center + r * (moved - center) + 0.005 * diagonal * Eigen::Vector3d::UnitX();
  }
  return pred;
}

enum Mode { kDense = 0, kRawVertices = 1, kPreviousDense = 2 };

void RunFrame(benchmark::State& state, const TriangleMesh& gt, const TriangleMesh& pred) {
  EvalOptions options;
  const auto mode = static_cast<Mode>(state.range(0));
  if (mode != kDense) options.gt_mode = GtMode::kVertices;
  if (mode == kPreviousDense) options.gt_max_edge = 0.02;
  FrameEval f;
  const std::clock_t cpu0 = std::clock();
  for (auto _ : state) f = EvaluatePair(pred, gt, options);
  const double cpu = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  state.counters["cpu_s"] = cpu / static_cast<double>(state.iterations());
  state.counters["chamfer_cm"] = f.ChamferCm();
  state.counters["F1"] = 100.0 * f.metrics.fscore[0];
  state.counters["F2"] = 100.0 * f.metrics.fscore[1];
  state.counters["icp_iterations"] = f.icp.iterations;
  state.counters["scale"] = f.initial_scale;
  state.counters["pred_points"] = f.num_pred_points;
  state.counters["gt_points"] = f.num_gt_points;
  state.SetLabel(mode == kDense         ? "dense"
                 : mode == kRawVertices ? "vertices"
                                        : "vertices+max-edge-0.02");
}

void BM_EvaluateFrame_Fox(benchmark::State& state) {
  static const TriangleMesh pred = Prediction(FoxFrame());
  RunFrame(state, FoxFrame(), pred);
}
BENCHMARK(BM_EvaluateFrame_Fox)
    ->Arg(kDense)
    ->Arg(kRawVertices)
    ->Arg(kPreviousDense)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

// The previous dense protocol is not run here: it would subdivide every
// triangle 5 times (about 37M vertices).
void BM_EvaluateFrame_Fox36k(benchmark::State& state) {
  static const TriangleMesh pred = Prediction(Fox36k());
  RunFrame(state, Fox36k(), pred);
}
BENCHMARK(BM_EvaluateFrame_Fox36k)
    ->Arg(kDense)
    ->Arg(kRawVertices)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

}  // namespace
}  // namespace banmo

BENCHMARK_MAIN();
