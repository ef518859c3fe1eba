#include "banmo/geometry/nearest_neighbors.h"

#include <gtest/gtest.h>

#include <random>

namespace banmo {
namespace {

Eigen::Matrix3Xd RandomPoints(int n, std::mt19937* rng, double scale = 1.0) {
  std::normal_distribution<double> gauss(0.0, scale);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) p.col(i) << gauss(*rng), gauss(*rng), gauss(*rng);
  return p;
}

void ExpectSameAsBruteForce(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& queries) {
  const KdTree3 tree(points);
  Eigen::VectorXi idx_tree, idx_brute;
  Eigen::VectorXd d_tree, d_brute;
  tree.Nearest(queries, &idx_tree, &d_tree);
  BruteForceNearest(points, queries, &idx_brute, &d_brute);
  ASSERT_EQ(idx_tree.size(), queries.cols());
  for (Eigen::Index i = 0; i < queries.cols(); ++i) {
    // Exact search: the same point (continuous random data has no ties) and
    // the very same squared distance (both sum the same three squares).
    EXPECT_EQ(idx_tree(i), idx_brute(i)) << "query " << i;
    EXPECT_EQ(d_tree(i), d_brute(i)) << "query " << i;
  }
}

TEST(KdTree3, EqualsBruteForceOnRandomSets) {
  std::mt19937 rng(7);
  for (const int n : {1, 2, 17, 1000, 5000}) {
    const Eigen::Matrix3Xd points = RandomPoints(n, &rng);
    ExpectSameAsBruteForce(points, RandomPoints(2000, &rng, 1.5));
  }
}

TEST(KdTree3, EqualsBruteForceOnClusteredAndFlatSets) {
  std::mt19937 rng(11);
  // Clusters of very different density, and a flat (z = 0) set: kd-tree
  // splits on degenerate axes.
  Eigen::Matrix3Xd clustered(3, 3000);
  clustered << RandomPoints(1000, &rng, 0.001),
      (RandomPoints(1000, &rng, 0.1).colwise() + Eigen::Vector3d(5, 0, 0)),
      RandomPoints(1000, &rng, 10.0);
  ExpectSameAsBruteForce(clustered, RandomPoints(3000, &rng, 3.0));
  Eigen::Matrix3Xd flat = RandomPoints(2000, &rng);
  flat.row(2).setZero();
  ExpectSameAsBruteForce(flat, RandomPoints(2000, &rng));
}

TEST(KdTree3, QueryOnIndexedPointsGivesZero) {
  std::mt19937 rng(3);
  const Eigen::Matrix3Xd points = RandomPoints(500, &rng);
  const KdTree3 tree(points);
  Eigen::VectorXi idx;
  Eigen::VectorXd d;
  tree.Nearest(points, &idx, &d);
  for (int i = 0; i < 500; ++i) {
    EXPECT_EQ(idx(i), i);
    EXPECT_EQ(d(i), 0.0);
  }
  EXPECT_EQ(tree.NumPoints(), 500);
  EXPECT_EQ(tree.Points(), points);
}

}  // namespace
}  // namespace banmo
