#include "banmo/eval/metrics.h"

#include "banmo/util/logging.h"

namespace banmo {
namespace {

double FractionBelow(const Eigen::VectorXd& d, double tau) {
  if (d.size() == 0) return 0.0;
  return static_cast<double>((d.array() < tau).count()) / static_cast<double>(d.size());
}

}  // namespace

DistanceMetrics ComputeDistanceMetrics(const Eigen::VectorXd& pred_to_gt,
                                       const Eigen::VectorXd& gt_to_pred, double longest_edge) {
  CHECK_GT(pred_to_gt.size(), 0);
  CHECK_GT(gt_to_pred.size(), 0);
  DistanceMetrics m;
  m.pred_to_gt = pred_to_gt.mean();
  m.gt_to_pred = gt_to_pred.mean();
  m.chamfer_sum = m.pred_to_gt + m.gt_to_pred;
  m.chamfer_mean = 0.5 * m.chamfer_sum;
  for (std::size_t k = 0; k < kFscoreFractions.size(); ++k) {
    const double tau = kFscoreFractions[k] * longest_edge;
    m.thresholds[k] = tau;
    m.precision[k] = FractionBelow(pred_to_gt, tau);
    m.recall[k] = FractionBelow(gt_to_pred, tau);
    const double pr = m.precision[k] + m.recall[k];
    m.fscore[k] = pr > 0.0 ? 2.0 * m.precision[k] * m.recall[k] / pr : 0.0;
  }
  return m;
}

}  // namespace banmo
