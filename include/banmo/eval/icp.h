// Iterative closest point up to a rigid motion or a similarity, with the
// closed-form weighted alignment of Umeyama (IEEE TPAMI 13(4), 1991) at every
// iteration, an optional robust weighting (trimmed or Huber), optional
// symmetric correspondences and a guard that keeps the scale away from zero.
#pragma once

#include <Eigen/Core>
#include <string>

#include "banmo/eval/surface_distance.h"
#include "banmo/geometry/nearest_neighbors.h"

namespace banmo {

// y = scale * rotation * x + translation.
struct Similarity {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Matrix3Xd Apply(const Eigen::Matrix3Xd& x) const;
  // x = rotation^T (y - translation) / scale.
  Eigen::Matrix3Xd ApplyInverse(const Eigen::Matrix3Xd& y) const;
};

// Weighted least-squares alignment (Umeyama 1991): minimises
//   sum_i w_i |s R x_i + t - y_i|^2
// over rotations R (det R = +1, no reflection), translations t and, if
// estimate_scale, s > 0 (else s = 1). `weights` may be empty (all ones).
// Needs at least one positive weight; with fewer than three non-collinear
// points the rotation is not unique and one minimiser is returned.
Similarity EstimateSimilarity(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                              const Eigen::VectorXd& weights, bool estimate_scale);

enum class RobustLoss {
  kNone,     // every correspondence has weight 1 (what pytorch3d's ICP does)
  kTrimmed,  // keep the trim_fraction closest correspondences (trimmed ICP)
  kHuber,    // IRLS Huber weights min(1, delta / r), delta = huber_factor * median(r)
};

// "none" | "trimmed" | "huber"; throws InputError naming `what` otherwise.
RobustLoss ParseRobustLoss(const std::string& name, const std::string& what = "robust loss");
std::string RobustLossName(RobustLoss loss);

struct IcpOptions {
  // Maximum number of correspondence/alignment rounds.
  int max_iterations = 100;
  // Converged when (rmse_prev - rmse) / rmse_prev < this (pytorch3d's rule),
  // or when the rmse is exactly zero.
  double relative_rmse_tolerance = 1e-6;
  // Estimate a scale (similarity ICP) or keep it fixed (rigid ICP).
  bool estimate_scale = false;
  // Also use target->source correspondences (each target point paired with
  // its nearest transformed source point). Penalises a shrinking source.
  bool symmetric = false;
  // Robust weighting of correspondences.
  RobustLoss robust = RobustLoss::kNone;
  // kTrimmed: fraction of correspondences kept, in (0, 1].
  double trim_fraction = 0.9;
  // kHuber: delta = huber_factor * median residual distance; > 0.
  double huber_factor = 2.0;
  // Scale guard (estimate_scale only): the scale stays within
  // [s0 / max_scale_change, s0 * max_scale_change] of the initial scale s0,
  // so it cannot collapse towards zero. >= 1.
  double max_scale_change = 4.0;
  // Use at most this many query points per direction (the first columns of
  // each point set; pass randomly ordered samples); 0 = all. The trees always
  // hold all points, so the nearest neighbours stay exact.
  int max_queries = 0;

  // Throws InputError naming the offending field.
  void Check() const;
};

struct IcpResult {
  Similarity source_to_target;  // maps source points onto the target
  int iterations = 0;           // rounds performed
  bool converged = false;       // relative rmse change fell below the tolerance
  bool scale_clamped = false;   // the scale guard was active at the end
  double initial_rmse = 0.0;    // (weighted) rmse of the first correspondences
  double final_rmse = 0.0;      // (weighted) rmse after the last alignment
};

// Aligns the points of `source` to those of `target` starting from `init`.
// Both trees are built once by the caller; `source` is needed for symmetric
// correspondences (queries of inverse-transformed target points).
IcpResult RunIcp(const KdTree3& source, const KdTree3& target, const Similarity& init,
                 const IcpOptions& options);

// The same loop with a triangle surface as the target: every iteration pairs
// each source point with its exact closest point on the surface
// (TriangleSurface3), then aligns as above. One-sided only (options.symmetric
// must be false, else InputError); options.max_queries limits the source
// points used (a prefix of the columns: pass them in random order).
IcpResult RunIcpToSurface(const Eigen::Matrix3Xd& source, const TriangleSurface3& target,
                          const Similarity& init, const IcpOptions& options);

}  // namespace banmo
