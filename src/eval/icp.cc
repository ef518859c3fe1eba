#include "banmo/eval/icp.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

Eigen::Matrix3Xd Similarity::Apply(const Eigen::Matrix3Xd& x) const {
  return ((scale * rotation) * x).colwise() + translation;
}

Eigen::Matrix3Xd Similarity::ApplyInverse(const Eigen::Matrix3Xd& y) const {
  return (rotation.transpose() * (y.colwise() - translation)) / scale;
}

Similarity EstimateSimilarity(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                              const Eigen::VectorXd& weights, bool estimate_scale) {
  CHECK_EQ(source.cols(), target.cols());
  CHECK_GT(source.cols(), 0);
  const Eigen::Index n = source.cols();
  const bool weighted = weights.size() > 0;
  if (weighted) CHECK_EQ(weights.size(), n);
  const double total = weighted ? weights.sum() : static_cast<double>(n);
  CHECK_GT(total, 0.0) << "EstimateSimilarity needs a positive weight";

  Eigen::Vector3d mu_x = Eigen::Vector3d::Zero();
  Eigen::Vector3d mu_y = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) {
    const double w = weighted ? weights(i) : 1.0;
    mu_x += w * source.col(i);
    mu_y += w * target.col(i);
  }
  mu_x /= total;
  mu_y /= total;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  // sum w (y - mu_y)(x - mu_x)^T / W
  double var_x = 0.0;                             // sum w |x - mu_x|^2 / W
  for (Eigen::Index i = 0; i < n; ++i) {
    const double w = weighted ? weights(i) : 1.0;
    if (w == 0.0) continue;
    const Eigen::Vector3d dx = source.col(i) - mu_x;
    cov += w * (target.col(i) - mu_y) * dx.transpose();
    var_x += w * dx.squaredNorm();
  }
  cov /= total;
  var_x /= total;

  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s_diag(1.0, 1.0, 1.0);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s_diag(2) = -1.0;
  Similarity result;
  result.rotation = svd.matrixU() * s_diag.asDiagonal() * svd.matrixV().transpose();
  if (estimate_scale && var_x > 0.0) {
    const double s = svd.singularValues().dot(s_diag) / var_x;
    // A negative or zero trace only happens for degenerate correspondences;
    // keep the scale positive (the ICP guard clamps it further).
    result.scale = s > 0.0 ? s : 1.0;
  }
  result.translation = mu_y - result.scale * result.rotation * mu_x;
  return result;
}

RobustLoss ParseRobustLoss(const std::string& name, const std::string& what) {
  if (name == "none") return RobustLoss::kNone;
  if (name == "trimmed") return RobustLoss::kTrimmed;
  if (name == "huber") return RobustLoss::kHuber;
  ThrowInputError(what, ": unknown value '", name, "' (expected none, trimmed or huber)");
}

std::string RobustLossName(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::kNone:
      return "none";
    case RobustLoss::kTrimmed:
      return "trimmed";
    case RobustLoss::kHuber:
      return "huber";
  }
  return "?";
}

void IcpOptions::Check() const {
  if (max_iterations < 0) ThrowInputError("icp max_iterations: must be >= 0, got ", max_iterations);
  if (!(relative_rmse_tolerance >= 0.0)) {
    ThrowInputError("icp relative_rmse_tolerance: must be >= 0, got ", relative_rmse_tolerance);
  }
  if (!(trim_fraction > 0.0 && trim_fraction <= 1.0)) {
    ThrowInputError("icp trim_fraction: must be in (0, 1], got ", trim_fraction);
  }
  if (!(huber_factor > 0.0)) ThrowInputError("icp huber_factor: must be > 0, got ", huber_factor);
  if (!(max_scale_change >= 1.0)) {
    ThrowInputError("icp max_scale_change: must be >= 1, got ", max_scale_change);
  }
  if (max_queries < 0) ThrowInputError("icp max_queries: must be >= 0, got ", max_queries);
}

namespace {

// Correspondence weights for the residual distances r (robust option).
Eigen::VectorXd RobustWeights(const Eigen::VectorXd& r, const IcpOptions& options) {
  const Eigen::Index n = r.size();
  Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  if (options.robust == RobustLoss::kNone || n == 0) return w;
  std::vector<double> sorted(r.data(), r.data() + n);
  if (options.robust == RobustLoss::kTrimmed) {
    const Eigen::Index keep = std::max<Eigen::Index>(
        1, static_cast<Eigen::Index>(std::ceil(options.trim_fraction * static_cast<double>(n))));
    if (keep >= n) return w;
    std::nth_element(sorted.begin(), sorted.begin() + (keep - 1), sorted.end());
    const double cutoff = sorted[static_cast<std::size_t>(keep - 1)];
    // Ties at the cutoff are all kept; that can exceed `keep` only on exact ties.
    for (Eigen::Index i = 0; i < n; ++i) w(i) = r(i) <= cutoff ? 1.0 : 0.0;
    return w;
  }
  // Huber IRLS: w = 1 inside delta, delta / r outside.
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
  const double delta = options.huber_factor * sorted[static_cast<std::size_t>(n / 2)];
  if (!(delta > 0.0)) return w;
  for (Eigen::Index i = 0; i < n; ++i) w(i) = r(i) <= delta ? 1.0 : delta / r(i);
  return w;
}

Eigen::Matrix3Xd Prefix(const Eigen::Matrix3Xd& points, int max_queries) {
  if (max_queries <= 0 || max_queries >= points.cols()) return points;
  return points.leftCols(max_queries);
}

double WeightedRmse(const Eigen::VectorXd& r, const Eigen::VectorXd& w) {
  const double total = w.sum();
  if (!(total > 0.0)) return 0.0;
  return std::sqrt(w.dot(r.cwiseAbs2()) / total);
}

}  // namespace

namespace {

// Closest points of a fixed set (kd-tree points or a surface) for each query.
using ClosestFn = std::function<void(const Eigen::Matrix3Xd& queries, Eigen::Matrix3Xd* closest)>;

// The ICP loop shared by RunIcp and RunIcpToSurface. `x` are the source
// queries, `y` the target queries (symmetric only); closest_in_target(T(x))
// and closest_in_source(T^-1(y)) give the partners.
IcpResult IcpLoop(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& y,
                  const ClosestFn& closest_in_target, const ClosestFn& closest_in_source,
                  const Similarity& init, const IcpOptions& options) {
  const Eigen::Index nx = x.cols();
  const Eigen::Index ny = options.symmetric ? y.cols() : 0;
  const double s0 = init.scale;
  CHECK_GT(s0, 0.0);
  const double scale_lo = s0 / options.max_scale_change;
  const double scale_hi = s0 * options.max_scale_change;

  IcpResult result;
  result.source_to_target = init;
  Similarity& transform = result.source_to_target;

  // Stacked correspondences: columns [0, nx) are source->target pairs,
  // [nx, nx + ny) target->source pairs (symmetric only).
  Eigen::Matrix3Xd src(3, nx + ny);
  Eigen::Matrix3Xd dst(3, nx + ny);
  Eigen::Matrix3Xd partners;
  double prev_rmse = -1.0;
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    closest_in_target(transform.Apply(x), &partners);
    src.leftCols(nx) = x;
    dst.leftCols(nx) = partners;
    if (ny > 0) {
      closest_in_source(transform.ApplyInverse(y), &partners);
      src.rightCols(ny) = partners;
      dst.rightCols(ny) = y;
    }
    // Residuals under the current transform give the robust weights.
    const Eigen::VectorXd r_before = (transform.Apply(src) - dst).colwise().norm().transpose();
    const Eigen::VectorXd w = RobustWeights(r_before, options);
    if (iter == 0) result.initial_rmse = WeightedRmse(r_before, w);

    Similarity next;
    if (options.estimate_scale) {
      next = EstimateSimilarity(src, dst, w, /*estimate_scale=*/true);
    } else {
      // Rigid with the given scale s0: align s0 * x to y rigidly.
      next = EstimateSimilarity(s0 * src, dst, w, /*estimate_scale=*/false);
      next.scale = s0;
    }
    result.scale_clamped = false;
    if (options.estimate_scale && (next.scale < scale_lo || next.scale > scale_hi)) {
      // Guard: clamp the scale and take the optimal translation for it.
      next.scale = std::clamp(next.scale, scale_lo, scale_hi);
      const double total = w.sum();
      const Eigen::Vector3d mu_x = src * w / total;
      const Eigen::Vector3d mu_y = dst * w / total;
      next.translation = mu_y - next.scale * next.rotation * mu_x;
      result.scale_clamped = true;
    }
    transform = next;
    result.iterations = iter + 1;
    const Eigen::VectorXd r_after = (transform.Apply(src) - dst).colwise().norm().transpose();
    const double rmse = WeightedRmse(r_after, w);
    result.final_rmse = rmse;
    if (rmse == 0.0 ||
        (prev_rmse > 0.0 && (prev_rmse - rmse) / prev_rmse < options.relative_rmse_tolerance)) {
      result.converged = true;
      break;
    }
    prev_rmse = rmse;
  }
  return result;
}

ClosestFn KdTreeClosest(const KdTree3& tree) {
  return [&tree](const Eigen::Matrix3Xd& queries, Eigen::Matrix3Xd* closest) {
    Eigen::VectorXi idx;
    Eigen::VectorXd sq;
    tree.Nearest(queries, &idx, &sq);
    closest->resize(3, queries.cols());
    for (Eigen::Index i = 0; i < queries.cols(); ++i) closest->col(i) = tree.Points().col(idx(i));
  };
}

}  // namespace

IcpResult RunIcp(const KdTree3& source, const KdTree3& target, const Similarity& init,
                 const IcpOptions& options) {
  options.Check();
  return IcpLoop(
      Prefix(source.Points(), options.max_queries),
      options.symmetric ? Prefix(target.Points(), options.max_queries) : Eigen::Matrix3Xd(3, 0),
      KdTreeClosest(target), KdTreeClosest(source), init, options);
}

IcpResult RunIcpToSurface(const Eigen::Matrix3Xd& source, const TriangleSurface3& target,
                          const Similarity& init, const IcpOptions& options) {
  options.Check();
  if (options.symmetric) {
    ThrowInputError("icp symmetric: not available against a surface (one-sided only)");
  }
  CHECK_GT(source.cols(), 0) << "RunIcpToSurface needs at least one source point";
  return IcpLoop(
      Prefix(source, options.max_queries), Eigen::Matrix3Xd(3, 0),
      [&target](const Eigen::Matrix3Xd& queries, Eigen::Matrix3Xd* closest) {
        Eigen::VectorXd sq;
        target.Closest(queries, closest, &sq);
      },
      ClosestFn(), init, options);
}

}  // namespace banmo
