// Exact nearest neighbours in 3-D: a FLANN kd-tree (KDTreeSingleIndex, searched
// with eps = 0, i.e. exact) and a brute-force reference. FLANN stays inside
// src/geometry/nearest_neighbors.cc.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

namespace banmo {

// A kd-tree over a fixed set of 3-D points, built once in the constructor.
// Queries are exact (same answers as BruteForceNearest up to ties between
// equidistant points) and may be issued from several threads.
class KdTree3 {
 public:
  // Copies `points` (3 x N, N >= 1) and builds the tree.
  explicit KdTree3(const Eigen::Matrix3Xd& points);
  ~KdTree3();
  KdTree3(KdTree3&&) noexcept;
  KdTree3& operator=(KdTree3&&) noexcept;
  KdTree3(const KdTree3&) = delete;
  KdTree3& operator=(const KdTree3&) = delete;

  int NumPoints() const;
  // The indexed points (3 x N), in the order given to the constructor.
  const Eigen::Matrix3Xd& Points() const;

  // For every query column q: index of its nearest indexed point and the
  // squared Euclidean distance to it. Parallel over queries (util/parallel.h).
  void Nearest(const Eigen::Matrix3Xd& queries, Eigen::VectorXi* indices,
               Eigen::VectorXd* squared_distances) const;

  // Index of the indexed point nearest to `query` and (if not null) the
  // squared distance to it. Thread-safe (one query, no parallelism inside:
  // for callers that are themselves parallel).
  int Nearest(const Eigen::Vector3d& query, double* squared_distance = nullptr) const;

  // The k nearest indexed points of every query column (k >= 1; fewer
  // columns are valid when the tree holds fewer than k points: the rest are
  // -1 with an infinite distance): column q of `indices` / `squared_distances`
  // (k x queries), in increasing distance.
  void NearestK(const Eigen::Matrix3Xd& queries, int k, Eigen::MatrixXi* indices,
                Eigen::MatrixXd* squared_distances) const;

  // Indices of the indexed points closer than `radius` to `query` (strictly)
  // and their squared distances, in no particular order. Thread-safe (one
  // query, no parallelism inside).
  void WithinRadius(const Eigen::Vector3d& query, double radius, std::vector<int>* indices,
                    std::vector<double>* squared_distances) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Reference O(N M) search with the same outputs as KdTree3::Nearest (ties go
// to the lowest index). Used by the tests and the benchmark.
void BruteForceNearest(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& queries,
                       Eigen::VectorXi* indices, Eigen::VectorXd* squared_distances);

}  // namespace banmo
