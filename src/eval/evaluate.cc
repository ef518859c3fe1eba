#include "banmo/eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <vector>

#include "banmo/eval/surface_distance.h"
#include "banmo/eval/surface_sampling.h"
#include "banmo/geometry/nearest_neighbors.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {

EvalProtocol ParseEvalProtocol(const std::string& name, const std::string& what) {
  if (name == "banmo") return EvalProtocol::kBanmo;
  if (name == "surface") return EvalProtocol::kSurface;
  ThrowInputError(what, ": unknown protocol '", name, "' (expected banmo or surface)");
}

std::string EvalProtocolName(EvalProtocol protocol) {
  return protocol == EvalProtocol::kBanmo ? "banmo" : "surface";
}

GtMode ParseGtMode(const std::string& name, const std::string& what) {
  if (name == "dense") return GtMode::kDense;
  if (name == "vertices") return GtMode::kVertices;
  ThrowInputError(what, ": unknown ground-truth mode '", name, "' (expected dense or vertices)");
}

std::string GtModeName(GtMode mode) { return mode == GtMode::kDense ? "dense" : "vertices"; }

void EvalOptions::Check() const {
  if (icp_iterations < 0) ThrowInputError("icp_iterations: must be >= 0, got ", icp_iterations);
  if (!(icp_relative_tolerance >= 0.0)) {
    ThrowInputError("icp_relative_tolerance: must be >= 0, got ", icp_relative_tolerance);
  }
  if (!(trim_fraction > 0.0 && trim_fraction <= 1.0)) {
    ThrowInputError("trim_fraction: must be in (0, 1], got ", trim_fraction);
  }
  if (!(huber_factor > 0.0)) ThrowInputError("huber_factor: must be > 0, got ", huber_factor);
  // 1e7 samples of two surfaces: ~0.5 GB of points and KD-trees.
  constexpr int kMaxSamples = 10000000;
  if (num_samples < 100 || num_samples > kMaxSamples) {
    ThrowInputError("num_samples: must be in [100, ", kMaxSamples, "], got ", num_samples);
  }
  if (dense_samples < 100 || dense_samples > kMaxSamples) {
    ThrowInputError("dense_samples: must be in [100, ", kMaxSamples, "], got ", dense_samples);
  }
  if (dense_icp_queries < 0) {
    ThrowInputError("dense_icp_queries: must be >= 0, got ", dense_icp_queries);
  }
  if (icp_max_queries < 0) ThrowInputError("icp_max_queries: must be >= 0, got ", icp_max_queries);
  if (!(max_scale_change >= 1.0)) {
    ThrowInputError("max_scale_change: must be >= 1, got ", max_scale_change);
  }
  if (!(gt_max_edge >= 0.0)) ThrowInputError("gt_max_edge: must be >= 0, got ", gt_max_edge);
  if (gt_max_edge > 0.0 && gt_mode == GtMode::kDense) {
    ThrowInputError(
        "gt_max_edge: subdivides the ground-truth vertices of gt mode 'vertices' "
        "(--gt-mode vertices); the default gt mode 'dense' already measures against "
        "the exact surface (docs/eval.md), got ",
        gt_max_edge);
  }
}

namespace {

void ValidateMesh(const TriangleMesh& mesh, const std::string& name, bool need_faces) {
  if (mesh.NumVertices() == 0) ThrowInputError(name, ": mesh is empty (expected vertices)");
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    if (!mesh.vertices.col(i).allFinite()) {
      ThrowInputError(name, ": vertex ", i,
                      " is not finite (NaN or Inf); expected finite coordinates");
    }
  }
  if (mesh.NumFaces() > 0 &&
      (mesh.faces.minCoeff() < 0 || mesh.faces.maxCoeff() >= mesh.NumVertices())) {
    ThrowInputError(name, ": a face refers to a vertex index outside [0, ", mesh.NumVertices(),
                    ")");
  }
  if (need_faces && !(MeshArea(mesh) > 0.0)) {
    ThrowInputError(name, ": mesh has no triangle with positive area (", mesh.NumFaces(),
                    " faces); the surface protocol and the dense ground truth (--gt-mode dense) "
                    "need a surface (a point-cloud ground truth: --gt-mode vertices)");
  }
}

double MedianDepth(const Eigen::Matrix3Xd& points) {
  std::vector<double> z(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) z[static_cast<std::size_t>(i)] = points(2, i);
  // torch.median returns the lower of the two middle values for even counts.
  const std::size_t mid = (z.size() - 1) / 2;
  std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(mid), z.end());
  return z[mid];
}

Eigen::Vector3d RmsAboutCentroid(const Eigen::Matrix3Xd& points, double* rms) {
  const Eigen::Vector3d c = points.rowwise().mean();
  *rms = std::sqrt((points.colwise() - c).colwise().squaredNorm().mean());
  return c;
}

void ThrowIfBehindCamera(double median_z, const std::string& name) {
  if (!(median_z > 0.0)) {
    ThrowInputError(name, ": median depth (z) is ", median_z,
                    "; the banmo protocol expects meshes in camera coordinates in front of the "
                    "camera (use --protocol surface for other coordinates)");
  }
}

bool HasArea(const TriangleMesh& mesh) { return mesh.NumFaces() > 0 && MeshArea(mesh) > 0.0; }

// The banmo protocol against a dense ground truth (GtMode::kDense): the GT is
// its surface. `out->gt_normalization` is set; fills the rest of `out`.
void EvaluateDense(const TriangleMesh& pred, const TriangleMesh& gt, const EvalOptions& options,
                   const std::string& pred_name, const std::string& gt_name,
                   double longest_normalized, FrameEval* out) {
  const double n = out->gt_normalization;
  // Both meshes are surfaces: `dense_samples` area-uniform samples of each
  // (random order, so the first icp_max_queries are a uniform subset for
  // ICP); the prediction's vertices if it has no triangle of positive area.
  const bool pred_has_area = HasArea(pred);
  Eigen::Matrix3Xd g = SampleSurface(gt, options.dense_samples, options.seed);
  Eigen::Matrix3Xd p = pred_has_area ? SampleSurface(pred, options.dense_samples, options.seed)
                                     : ShuffleColumns(pred.vertices, options.seed);
  // Median depths over the samples (the surfaces' median depths).
  const double z_pred = MedianDepth(p);
  const double z_gt = MedianDepth(g);
  ThrowIfBehindCamera(z_pred, pred_name);
  ThrowIfBehindCamera(z_gt, gt_name);
  out->initial_scale = z_gt / z_pred;
  p *= out->initial_scale * n;
  g *= n;
  out->num_pred_points = static_cast<int>(p.cols());
  out->num_gt_points = static_cast<int>(g.cols());

  // The GT surface, built once: ICP and prediction->GT distances.
  const TriangleSurface3 gt_surface(gt, n);
  if (options.icp_iterations > 0) {
    IcpOptions icp;
    icp.max_iterations = options.icp_iterations;
    icp.relative_rmse_tolerance = options.icp_relative_tolerance;
    icp.estimate_scale = false;  // rigid from the identity, as BANMo's script
    icp.symmetric = false;
    icp.robust = options.robust;
    icp.trim_fraction = options.trim_fraction;
    icp.huber_factor = options.huber_factor;
    icp.max_queries = options.dense_icp_queries;
    out->icp = RunIcpToSurface(p, gt_surface, Similarity(), icp);
  }
  const Similarity& t = out->icp.source_to_target;

  Eigen::Matrix3Xd closest;
  Eigen::VectorXd sq;
  gt_surface.Closest(t.Apply(p), &closest, &sq);
  const Eigen::VectorXd pred_to_gt = sq.cwiseSqrt();
  // GT->prediction: to the predicted surface when it has triangles, else to
  // its vertices; searched in the untransformed prediction,
  // d(q, T(P)) = s * d(T^-1(q), P).
  if (pred_has_area) {
    const TriangleSurface3 pred_surface(pred, out->initial_scale * n);
    pred_surface.Closest(t.ApplyInverse(g), &closest, &sq);
  } else {
    Eigen::VectorXi idx;
    KdTree3(p).Nearest(t.ApplyInverse(g), &idx, &sq);
  }
  const Eigen::VectorXd gt_to_pred = t.scale * sq.cwiseSqrt();
  out->metrics = ComputeDistanceMetrics(pred_to_gt, gt_to_pred, longest_normalized);
}

}  // namespace

TriangleMesh SubdivideToMaxEdge(const TriangleMesh& mesh, double max_edge, int max_rounds) {
  CHECK_GT(max_edge, 0.0);
  TriangleMesh current = mesh;
  for (int round = 0; round < max_rounds; ++round) {
    double longest = 0.0;
    for (int f = 0; f < current.NumFaces(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int a = current.faces(k, f), b = current.faces((k + 1) % 3, f);
        longest = std::max(longest, (current.vertices.col(a) - current.vertices.col(b)).norm());
      }
    }
    if (longest <= max_edge) break;
    std::map<std::pair<int, int>, int> midpoint;
    std::vector<Eigen::Vector3d> vertices;
    std::vector<Eigen::Vector3d> colors;
    for (int v = 0; v < current.NumVertices(); ++v) {
      vertices.push_back(current.vertices.col(v));
      if (current.HasColors()) colors.push_back(current.colors.col(v).cast<double>());
    }
    auto mid = [&](int a, int b) {
      const std::pair<int, int> key(std::min(a, b), std::max(a, b));
      const auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      vertices.push_back(0.5 * (current.vertices.col(a) + current.vertices.col(b)));
      if (current.HasColors()) {
        colors.push_back(
            0.5 * (current.colors.col(a).cast<double>() + current.colors.col(b).cast<double>()));
      }
      return midpoint[key] = static_cast<int>(vertices.size()) - 1;
    };
    Eigen::Matrix3Xi faces(3, 4 * current.NumFaces());
    for (int f = 0; f < current.NumFaces(); ++f) {
      const int a = current.faces(0, f), b = current.faces(1, f), c = current.faces(2, f);
      const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      faces.col(4 * f + 0) << a, ab, ca;
      faces.col(4 * f + 1) << ab, b, bc;
      faces.col(4 * f + 2) << ca, bc, c;
      faces.col(4 * f + 3) << ab, bc, ca;
    }
    TriangleMesh next;
    next.vertices.resize(3, vertices.size());
    for (size_t v = 0; v < vertices.size(); ++v) next.vertices.col(v) = vertices[v];
    next.faces = faces;
    if (current.HasColors()) {
      next.colors.resize(3, colors.size());
      for (size_t v = 0; v < colors.size(); ++v) {
        next.colors.col(v) = colors[v].array().round().cast<std::uint8_t>().matrix();
      }
    }
    current = std::move(next);
  }
  return current;
}

FrameEval EvaluatePair(const TriangleMesh& pred, const TriangleMesh& gt, const EvalOptions& options,
                       const std::string& pred_name, const std::string& gt_name) {
  options.Check();
  const bool surface = options.protocol == EvalProtocol::kSurface;
  const bool dense_gt = !surface && options.gt_mode == GtMode::kDense;
  ValidateMesh(pred, pred_name, surface);
  ValidateMesh(gt, gt_name, surface || dense_gt);

  FrameEval out;
  out.pred_name = pred_name;
  out.gt_name = gt_name;

  // Normalisation: the GT's longest bounding-box edge becomes 2 (half-extent 1).
  const Eigen::Vector3d extent =
      gt.vertices.rowwise().maxCoeff() - gt.vertices.rowwise().minCoeff();
  const double longest = extent.maxCoeff();
  if (!(longest > 0.0)) {
    ThrowInputError(gt_name, ": ground-truth mesh has zero extent (all vertices coincide)");
  }
  out.gt_normalization = 2.0 / longest;
  const double longest_normalized = longest * out.gt_normalization;  // = 2 up to rounding

  if (!surface && options.gt_mode == GtMode::kDense) {
    EvaluateDense(pred, gt, options, pred_name, gt_name, longest_normalized, &out);
    return out;
  }

  Eigen::Matrix3Xd p;
  Eigen::Matrix3Xd g;
  Similarity init;
  if (!surface) {
    p = pred.vertices;
    g = options.gt_max_edge > 0.0
            ? SubdivideToMaxEdge(gt, options.gt_max_edge / out.gt_normalization).vertices
            : gt.vertices;
    const double z_pred = MedianDepth(p);
    const double z_gt = MedianDepth(g);
    if (!(z_pred > 0.0)) {
      ThrowInputError(pred_name, ": median depth (z) is ", z_pred,
                      "; the banmo protocol expects meshes in camera coordinates in front of the "
                      "camera (use --protocol surface for other coordinates)");
    }
    if (!(z_gt > 0.0)) {
      ThrowInputError(gt_name, ": median depth (z) is ", z_gt,
                      "; the banmo protocol expects meshes in camera coordinates in front of the "
                      "camera (use --protocol surface for other coordinates)");
    }
    out.initial_scale = z_gt / z_pred;
    p *= out.initial_scale * out.gt_normalization;
    g *= out.gt_normalization;
    // Rigid ICP from identity.
  } else {
    p = SampleSurface(pred, options.num_samples, options.seed);
    g = SampleSurface(gt, options.num_samples, options.seed);
    double rms_p = 0.0;
    double rms_g = 0.0;
    const Eigen::Vector3d c_p = RmsAboutCentroid(p, &rms_p);
    const Eigen::Vector3d c_g = RmsAboutCentroid(g, &rms_g);
    if (!(rms_p > 0.0)) ThrowInputError(pred_name, ": predicted surface has zero extent");
    out.initial_scale = rms_g / rms_p;
    p *= out.initial_scale * out.gt_normalization;
    g *= out.gt_normalization;
    // Start with the centroids on top of each other.
    init.translation = (c_g - out.initial_scale * c_p) * out.gt_normalization;
  }
  out.num_pred_points = static_cast<int>(p.cols());
  out.num_gt_points = static_cast<int>(g.cols());

  // One kd-tree per side for this frame; used by ICP and the final distances.
  const KdTree3 pred_tree(p);
  const KdTree3 gt_tree(g);
  if (options.icp_iterations > 0) {
    IcpOptions icp;
    icp.max_iterations = options.icp_iterations;
    icp.relative_rmse_tolerance = options.icp_relative_tolerance;
    icp.estimate_scale = surface;
    icp.symmetric = surface && options.symmetric_icp;
    icp.robust = options.robust;
    icp.trim_fraction = options.trim_fraction;
    icp.huber_factor = options.huber_factor;
    icp.max_scale_change = options.max_scale_change;
    icp.max_queries = surface ? options.icp_max_queries : 0;
    out.icp = RunIcp(pred_tree, gt_tree, init, icp);
  } else {
    out.icp.source_to_target = init;
  }
  const Similarity& t = out.icp.source_to_target;

  // Exact distances both ways. gt->pred is searched in the untransformed
  // prediction's tree: d(q, T(P)) = s * d(T^-1(q), P).
  Eigen::VectorXi idx;
  Eigen::VectorXd sq;
  gt_tree.Nearest(t.Apply(p), &idx, &sq);
  const Eigen::VectorXd pred_to_gt = sq.cwiseSqrt();
  pred_tree.Nearest(t.ApplyInverse(g), &idx, &sq);
  const Eigen::VectorXd gt_to_pred = t.scale * sq.cwiseSqrt();
  out.metrics = ComputeDistanceMetrics(pred_to_gt, gt_to_pred, longest_normalized);
  return out;
}

void Summarize(EvalReport* report) {
  const int n = static_cast<int>(report->frames.size());
  report->chamfer_cm = report->chamfer_mean_cm = 0.0;
  report->pred_to_gt_cm = report->gt_to_pred_cm = 0.0;
  report->fscore_percent = {0.0, 0.0, 0.0};
  report->worst_chamfer_frame = -1;
  report->worst_fscore_frame = {-1, -1, -1};
  report->icp_converged_frames = 0;
  if (n == 0) return;
  for (int i = 0; i < n; ++i) {
    const FrameEval& f = report->frames[static_cast<std::size_t>(i)];
    report->chamfer_cm += f.ChamferCm() / n;
    report->chamfer_mean_cm += f.ChamferMeanCm() / n;
    report->pred_to_gt_cm += 100.0 * f.metrics.pred_to_gt / n;
    report->gt_to_pred_cm += 100.0 * f.metrics.gt_to_pred / n;
    if (f.icp.converged) ++report->icp_converged_frames;
    if (report->worst_chamfer_frame < 0 ||
        f.metrics.chamfer_sum >
            report->frames[static_cast<std::size_t>(report->worst_chamfer_frame)]
                .metrics.chamfer_sum) {
      report->worst_chamfer_frame = i;
    }
    for (std::size_t k = 0; k < 3; ++k) {
      report->fscore_percent[k] += 100.0 * f.metrics.fscore[k] / n;
      int& worst = report->worst_fscore_frame[k];
      if (worst < 0 ||
          f.metrics.fscore[k] < report->frames[static_cast<std::size_t>(worst)].metrics.fscore[k]) {
        worst = i;
      }
    }
  }
}

EvalReport EvaluateSequence(const std::vector<TriangleMesh>& pred,
                            const std::vector<TriangleMesh>& gt, const EvalOptions& options,
                            const std::vector<std::string>& pred_names,
                            const std::vector<std::string>& gt_names,
                            const FrameCallback& on_frame) {
  options.Check();
  if (pred.size() != gt.size()) {
    ThrowInputError("frame counts differ: ", pred.size(), " predicted meshes but ", gt.size(),
                    " ground-truth meshes (expected one prediction per ground-truth frame)");
  }
  if (pred.empty()) ThrowInputError("no frames to evaluate (expected at least one mesh)");
  CHECK(pred_names.empty() || pred_names.size() == pred.size());
  CHECK(gt_names.empty() || gt_names.size() == gt.size());
  EvalReport report;
  report.protocol = options.protocol;
  report.gt_mode = options.gt_mode;
  // Frames in parallel: each writes its own slot; the passes inside a frame
  // (kd-tree queries, surface distances) then run their chunks in turn on
  // that frame's thread, split as they would be alone, so every number is
  // the same as one frame at a time (util/parallel.h).
  const int n = static_cast<int>(pred.size());
  report.frames.resize(pred.size());
  std::mutex progress_mutex;
  int done = 0;
  ParallelFor(n, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const std::size_t k = static_cast<std::size_t>(i);
      const std::string frame = "frame " + std::to_string(i);
      report.frames[k] = EvaluatePair(pred[k], gt[k], options,
                                      pred_names.empty() ? frame + " (prediction)" : pred_names[k],
                                      gt_names.empty() ? frame + " (ground truth)" : gt_names[k]);
      if (on_frame) {
        const std::lock_guard<std::mutex> lock(progress_mutex);
        on_frame(i, ++done, report.frames[k]);
      }
    }
  });
  Summarize(&report);
  return report;
}

}  // namespace banmo
