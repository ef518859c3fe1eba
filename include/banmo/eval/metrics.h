// Chamfer distance and F-score from nearest-neighbour distances.
#pragma once

#include <Eigen/Core>
#include <array>

namespace banmo {

// F-score thresholds as fractions of the ground truth's longest axis-aligned
// bounding-box edge (BANMo, Sec. 4.1: 1 %, 2 %, 5 %).
inline constexpr std::array<double, 3> kFscoreFractions = {0.01, 0.02, 0.05};

struct DistanceMetrics {
  double pred_to_gt = 0.0;   // mean over predicted points of the distance to the GT (accuracy)
  double gt_to_pred = 0.0;   // mean over GT points of the distance to the prediction (completeness)
  double chamfer_sum = 0.0;  // pred_to_gt + gt_to_pred (BANMo's convention)
  double chamfer_mean = 0.0;           // (pred_to_gt + gt_to_pred) / 2
  std::array<double, 3> thresholds{};  // absolute thresholds tau used below
  std::array<double, 3> precision{};   // fraction of predicted points with d < tau
  std::array<double, 3> recall{};      // fraction of GT points with d < tau
  std::array<double, 3> fscore{};      // 2 P R / (P + R), 0 when P + R = 0
};

// From the (non-squared) distances of every predicted point to the GT and of
// every GT point to the prediction; tau_k = kFscoreFractions[k] * longest_edge.
// A point counts as matched when d < tau (strict, as BANMo's script).
DistanceMetrics ComputeDistanceMetrics(const Eigen::VectorXd& pred_to_gt,
                                       const Eigen::VectorXd& gt_to_pred, double longest_edge);

}  // namespace banmo
