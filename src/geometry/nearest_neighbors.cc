#include "banmo/geometry/nearest_neighbors.h"

#include <flann/algorithms/dist.h>
#include <flann/algorithms/kdtree_single_index.h>
#include <flann/util/result_set.h>

#include <algorithm>
#include <limits>
#include <vector>

#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {

// FLANN's single kd-tree (no randomisation) searched with eps = 0 visits every
// cell that can hold a closer point, so the search is exact; "checks" does not
// apply to this index. reorder = true copies the points into leaf order for
// locality; results still carry the original indices.
struct KdTree3::Impl {
  using Distance = flann::L2_Simple<double>;
  explicit Impl(const Eigen::Matrix3Xd& pts)
      : points(pts),
        index(flann::Matrix<double>(points.data(), static_cast<std::size_t>(points.cols()), 3),
              flann::KDTreeSingleIndexParams(/*leaf_max_size=*/10, /*reorder=*/true)) {
    index.buildIndex();
  }
  Eigen::Matrix3Xd points;  // must outlive index construction (FLANN copies on reorder)
  flann::KDTreeSingleIndex<Distance> index;
};

KdTree3::KdTree3(const Eigen::Matrix3Xd& points) {
  CHECK_GT(points.cols(), 0) << "KdTree3 needs at least one point";
  impl_ = std::make_unique<Impl>(points);
}
KdTree3::~KdTree3() = default;
KdTree3::KdTree3(KdTree3&&) noexcept = default;
KdTree3& KdTree3::operator=(KdTree3&&) noexcept = default;

int KdTree3::NumPoints() const { return static_cast<int>(impl_->points.cols()); }
const Eigen::Matrix3Xd& KdTree3::Points() const { return impl_->points; }

void KdTree3::Nearest(const Eigen::Matrix3Xd& queries, Eigen::VectorXi* indices,
                      Eigen::VectorXd* squared_distances) const {
  const int n = static_cast<int>(queries.cols());
  indices->resize(n);
  squared_distances->resize(n);
  flann::SearchParams params;
  params.eps = 0.0f;  // exact
  params.checks = flann::FLANN_CHECKS_UNLIMITED;
  params.sorted = false;
  ParallelFor(n, [&](int begin, int end) {
    flann::KNNSimpleResultSet<double> result(1);
    for (int i = begin; i < end; ++i) {
      result.clear();
      impl_->index.findNeighbors(result, queries.col(i).data(), params);
      std::size_t index = 0;
      double dist = 0.0;
      result.copy(&index, &dist, 1, false);
      (*indices)(i) = static_cast<int>(index);
      (*squared_distances)(i) = dist;
    }
  });
}

int KdTree3::Nearest(const Eigen::Vector3d& query, double* squared_distance) const {
  flann::SearchParams params;
  params.eps = 0.0f;  // exact
  params.checks = flann::FLANN_CHECKS_UNLIMITED;
  params.sorted = false;
  flann::KNNSimpleResultSet<double> result(1);
  impl_->index.findNeighbors(result, query.data(), params);
  std::size_t index = 0;
  double dist = 0.0;
  result.copy(&index, &dist, 1, false);
  if (squared_distance != nullptr) *squared_distance = dist;
  return static_cast<int>(index);
}

void KdTree3::NearestK(const Eigen::Matrix3Xd& queries, int k, Eigen::MatrixXi* indices,
                       Eigen::MatrixXd* squared_distances) const {
  CHECK_GE(k, 1);
  const int n = static_cast<int>(queries.cols());
  indices->setConstant(k, n, -1);
  squared_distances->setConstant(k, n, std::numeric_limits<double>::infinity());
  const int found = std::min(k, NumPoints());
  flann::SearchParams params;
  params.eps = 0.0f;  // exact
  params.checks = flann::FLANN_CHECKS_UNLIMITED;
  params.sorted = true;
  ParallelFor(n, [&](int begin, int end) {
    flann::KNNSimpleResultSet<double> result(static_cast<std::size_t>(found));
    std::vector<std::size_t> index(static_cast<std::size_t>(found));
    for (int i = begin; i < end; ++i) {
      result.clear();
      impl_->index.findNeighbors(result, queries.col(i).data(), params);
      result.copy(index.data(), squared_distances->col(i).data(), static_cast<std::size_t>(found),
                  true);
      for (int j = 0; j < found; ++j) {
        (*indices)(j, i) = static_cast<int>(index[static_cast<std::size_t>(j)]);
      }
    }
  });
}

void KdTree3::WithinRadius(const Eigen::Vector3d& query, double radius, std::vector<int>* indices,
                           std::vector<double>* squared_distances) const {
  indices->clear();
  squared_distances->clear();
  if (!(radius > 0.0)) return;
  flann::SearchParams params;
  params.eps = 0.0f;  // exact
  params.checks = flann::FLANN_CHECKS_UNLIMITED;
  params.sorted = false;
  flann::RadiusResultSet<double> result(radius * radius);  // L2_Simple: squared
  impl_->index.findNeighbors(result, query.data(), params);
  const std::size_t n = result.size();
  std::vector<std::size_t> index(n);
  squared_distances->resize(n);
  if (n > 0) result.copy(index.data(), squared_distances->data(), n, false);
  indices->reserve(n);
  for (const std::size_t i : index) indices->push_back(static_cast<int>(i));
}

void BruteForceNearest(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& queries,
                       Eigen::VectorXi* indices, Eigen::VectorXd* squared_distances) {
  CHECK_GT(points.cols(), 0);
  const int n = static_cast<int>(queries.cols());
  indices->resize(n);
  squared_distances->resize(n);
  ParallelFor(n, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const Eigen::Vector3d q = queries.col(i);
      double best = std::numeric_limits<double>::infinity();
      int best_index = -1;
      for (Eigen::Index j = 0; j < points.cols(); ++j) {
        const double d = (points.col(j) - q).squaredNorm();
        if (d < best) {
          best = d;
          best_index = static_cast<int>(j);
        }
      }
      (*indices)(i) = best_index;
      (*squared_distances)(i) = best;
    }
  });
}

}  // namespace banmo
