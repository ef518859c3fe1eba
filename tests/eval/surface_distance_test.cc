#include "banmo/eval/surface_distance.h"

#include <CGAL/Simple_cartesian.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "banmo/eval/icp.h"
#include "banmo/eval/surface_sampling.h"
#include "banmo/geometry/nearest_neighbors.h"
#include "banmo/util/error.h"
#include "test_shapes.h"

namespace banmo {
namespace {

using testing::Blob;

// Uniform in [-1, 1) from a seeded mt19937_64 (53 bits, portable).
class Uniform {
 public:
  explicit Uniform(std::uint64_t seed) : engine_(seed) {}
  double operator()() { return 2.0 * static_cast<double>(engine_() >> 11) * 0x1.0p-53 - 1.0; }
  Eigen::Vector3d Vector() {
    const double x = (*this)(), y = (*this)(), z = (*this)();
    return Eigen::Vector3d(x, y, z);
  }

 private:
  std::mt19937_64 engine_;
};

// Reference: CGAL's squared distance between a point and a triangle.
double CgalSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                           const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  using K = CGAL::Simple_cartesian<double>;
  const K::Triangle_3 t(K::Point_3(a.x(), a.y(), a.z()), K::Point_3(b.x(), b.y(), b.z()),
                        K::Point_3(c.x(), c.y(), c.z()));
  return CGAL::squared_distance(K::Point_3(p.x(), p.y(), p.z()), t);
}

TEST(ClosestPointOnTriangle, MatchesCgalOnRandomTrianglesAndPoints) {
  Uniform u(7);
  for (int trial = 0; trial < 20000; ++trial) {
    const Eigen::Vector3d a = u.Vector(), b = u.Vector();
    Eigen::Vector3d c = u.Vector();
    if (trial % 10 == 0) c = a + 0.5 * (b - a);  // collinear
    if (trial % 10 == 1) c = a;                  // two corners coincide
    const Eigen::Vector3d p = 2.0 * u.Vector();
    const Eigen::Vector3d x = ClosestPointOnTriangle(p, a, b, c);
    const double ours = (x - p).squaredNorm();
    if (trial % 10 > 1) {  // CGAL needs a non-degenerate triangle
      EXPECT_NEAR(ours, CgalSquaredDistance(p, a, b, c), 1e-12) << trial;
    }
    // The point lies in the triangle (convex hull of a, b, c): its distance
    // is never below the distance to the plane and never above the corners.
    EXPECT_LE(
        ours,
        std::min({(p - a).squaredNorm(), (p - b).squaredNorm(), (p - c).squaredNorm()}) + 1e-12);
  }
}

TEST(TriangleSurface3, MatchesBruteForceOverAllTriangles) {
  // A low-poly blob (large triangles, like the glTF Fox) and a fine one.
  for (const auto& [rings, segments] : {std::pair<int, int>{6, 8}, {32, 64}}) {
    const TriangleMesh mesh = Blob(Eigen::Vector3d(0.2, -0.1, 3.0), rings, segments);
    const TriangleSurface3 surface(mesh);
    // Queries near the surface (samples moved by up to 0.001 .. 0.3) and far.
    Uniform u(11);
    const Eigen::Matrix3Xd samples = SampleSurface(mesh, 4000, 3);
    Eigen::Matrix3Xd queries(3, samples.cols() + 500);
    const double offsets[] = {0.001, 0.01, 0.05, 0.3};
    for (Eigen::Index i = 0; i < samples.cols(); ++i) {
      queries.col(i) = samples.col(i) + offsets[i % 4] * u.Vector();
    }
    for (Eigen::Index i = samples.cols(); i < queries.cols(); ++i) {
      queries.col(i) = Eigen::Vector3d(0.2, -0.1, 3.0) + 3.0 * u.Vector();
    }
    Eigen::Matrix3Xd fast_points, ref_points;
    Eigen::VectorXd fast, ref;
    int radius_searches = -1;
    surface.Closest(queries, &fast_points, &fast, &radius_searches);
    surface.ClosestBruteForce(queries, &ref_points, &ref);
    for (Eigen::Index i = 0; i < queries.cols(); ++i) {
      EXPECT_NEAR(fast(i), ref(i), 1e-12 * (1.0 + ref(i))) << rings << " rings, query " << i;
      EXPECT_NEAR((fast_points.col(i) - queries.col(i)).squaredNorm(), fast(i), 1e-12);
    }
    // Both paths are exercised: the 4 nearest seeds certify many queries
    // near the surface, far ones need the radius search.
    EXPECT_GT(radius_searches, 0) << rings << " rings";
    EXPECT_LT(radius_searches, queries.cols()) << rings << " rings";
  }
}

TEST(TriangleSurface3, SeedsCoverEveryTriangle) {
  // Large triangles (a low-poly blob) and a coarse seed spacing: every point
  // of the surface has a seed within SeedCover() <= spacing / sqrt(3).
  const TriangleMesh mesh = Blob(Eigen::Vector3d(0, 0, 3), 6, 8);
  for (const double spacing : {0.05, 0.3, 10.0}) {
    const TriangleSurface3 surface(mesh, 1.0, spacing);
    EXPECT_GE(surface.NumSeeds(), surface.NumTriangles());
    EXPECT_LE(surface.SeedCover(), spacing / std::sqrt(3.0) * (1.0 + 1e-6) + 1e-12);
    const Eigen::Matrix3Xd on = SampleSurface(mesh, 20000, 4);
    // The nearest seed of any point of any triangle is within the cover of
    // some seed, so within the cover of the nearest one.
    Eigen::Matrix3Xd points;
    Eigen::VectorXd sq;
    surface.Closest(on, &points, &sq);
    EXPECT_LT(sq.maxCoeff(), 1e-20) << spacing;
  }
}

TEST(TriangleSurface3, PointsOnTheSurfaceHaveZeroDistance) {
  const TriangleMesh mesh = Blob(Eigen::Vector3d(0, 0, 3), 6, 8);
  const TriangleSurface3 surface(mesh, 2.0);  // scaled copy
  const Eigen::Matrix3Xd on = 2.0 * SampleSurface(mesh, 5000, 9);
  Eigen::Matrix3Xd points;
  Eigen::VectorXd sq;
  surface.Closest(on, &points, &sq);
  EXPECT_LT(sq.maxCoeff(), 1e-24);
}

TEST(TriangleSurface3, BadMeshesAreErrors) {
  TriangleMesh flat;
  flat.vertices.resize(3, 3);
  flat.vertices << 0, 1, 2, 0, 0, 0, 0, 0, 0;  // collinear
  flat.faces.resize(3, 1);
  flat.faces << 0, 1, 2;
  EXPECT_THROW(TriangleSurface3{flat}, InputError);
  TriangleMesh bad = Blob(Eigen::Vector3d(0, 0, 3), 6, 8);
  bad.faces(1, 3) = -1;
  EXPECT_THROW(TriangleSurface3{bad}, InputError);
}

// A diverged solve's mesh: a blob with one vertex moved 1e7 units away
// (the triangles around it stretched) would need about 3e16 seeds at the
// default spacing. The spacing widens
// to fit max_seeds (here 2e4, to keep the test small), and the distances
// stay exact.
TEST(TriangleSurface3, HugeTrianglesWidenTheSeedSpacing) {
  TriangleMesh mesh = Blob(Eigen::Vector3d(0, 0, 3), 6, 8);
  mesh.vertices.col(mesh.faces(0, 5)) = Eigen::Vector3d(1e7, -2e6, 5e6);
  const TriangleSurface3 surface(mesh, 1.0, 0.04, 2e4);
  EXPECT_EQ(surface.NumTriangles(), mesh.NumFaces());
  EXPECT_LE(surface.NumSeeds(), 2e4);
  Uniform u(5);
  Eigen::Matrix3Xd queries(3, 300);
  for (Eigen::Index i = 0; i < queries.cols(); ++i) {
    queries.col(i) = (i % 3 == 0 ? 1e6 : 2.0) * u.Vector() + Eigen::Vector3d(0, 0, 3);
  }
  Eigen::Matrix3Xd fast_points, ref_points;
  Eigen::VectorXd fast, ref;
  surface.Closest(queries, &fast_points, &fast);
  surface.ClosestBruteForce(queries, &ref_points, &ref);
  for (Eigen::Index i = 0; i < queries.cols(); ++i) {
    EXPECT_NEAR(fast(i), ref(i), 1e-12 * (1.0 + ref(i))) << "query " << i;
  }
}

// Triangles with a non-finite corner are left out; a mesh of nothing else
// is an error.
TEST(TriangleSurface3, NonFiniteTrianglesAreLeftOut) {
  TriangleMesh mesh = Blob(Eigen::Vector3d(0, 0, 3), 6, 8);
  const int faces = mesh.NumFaces();
  int touching = 0;
  const int v = mesh.faces(0, 0);
  for (int f = 0; f < faces; ++f) {
    touching += mesh.faces(0, f) == v || mesh.faces(1, f) == v || mesh.faces(2, f) == v;
  }
  mesh.vertices(1, v) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(TriangleSurface3(mesh).NumTriangles(), faces - touching);
  mesh.vertices.setConstant(std::numeric_limits<double>::infinity());
  EXPECT_THROW(TriangleSurface3{mesh}, InputError);
}

TEST(KdTree3, NearestKMatchesSortedBruteForce) {
  Uniform u(5);
  Eigen::Matrix3Xd points(3, 3000), queries(3, 200);
  for (Eigen::Index i = 0; i < points.cols(); ++i) points.col(i) = u.Vector();
  for (Eigen::Index i = 0; i < queries.cols(); ++i) queries.col(i) = 1.2 * u.Vector();
  const KdTree3 tree(points);
  Eigen::MatrixXi idx;
  Eigen::MatrixXd sq;
  tree.NearestK(queries, 6, &idx, &sq);
  for (Eigen::Index q = 0; q < queries.cols(); ++q) {
    std::vector<double> all;
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      all.push_back((points.col(i) - queries.col(q)).squaredNorm());
    }
    std::sort(all.begin(), all.end());
    for (int j = 0; j < 6; ++j) {
      EXPECT_DOUBLE_EQ(sq(j, q), all[static_cast<std::size_t>(j)]);
      EXPECT_DOUBLE_EQ((points.col(idx(j, q)) - queries.col(q)).squaredNorm(), sq(j, q));
    }
  }
  // More neighbours than points: the rest are -1.
  const KdTree3 small(points.leftCols(2));
  small.NearestK(queries.leftCols(1), 4, &idx, &sq);
  EXPECT_GE(idx(1, 0), 0);
  EXPECT_EQ(idx(2, 0), -1);
}

TEST(KdTree3, SingleQueryNearestMatchesBruteForce) {
  Uniform u(6);
  Eigen::Matrix3Xd points(3, 2500), queries(3, 300);
  for (Eigen::Index i = 0; i < points.cols(); ++i) points.col(i) = u.Vector();
  // Points on a plane (z = 0) too: the bone registration's 2-D use.
  points.row(2).rightCols(1000).setZero();
  for (Eigen::Index i = 0; i < queries.cols(); ++i) queries.col(i) = 1.3 * u.Vector();
  queries.row(2).rightCols(100).setZero();
  const KdTree3 tree(points);
  Eigen::VectorXi expected;
  Eigen::VectorXd expected_sq;
  BruteForceNearest(points, queries, &expected, &expected_sq);
  for (Eigen::Index q = 0; q < queries.cols(); ++q) {
    double sq = -1.0;
    const int i = tree.Nearest(Eigen::Vector3d(queries.col(q)), &sq);
    ASSERT_GE(i, 0);
    ASSERT_LT(i, points.cols());
    // Exact: the same distance as the brute-force search (the index may
    // differ only between equidistant points).
    EXPECT_DOUBLE_EQ(sq, expected_sq(q));
    EXPECT_DOUBLE_EQ((points.col(i) - queries.col(q)).squaredNorm(), sq);
    EXPECT_EQ(tree.Nearest(Eigen::Vector3d(queries.col(q))), i);
  }
}

TEST(KdTree3, WithinRadiusMatchesBruteForce) {
  Uniform u(8);
  Eigen::Matrix3Xd points(3, 2000);
  for (Eigen::Index i = 0; i < points.cols(); ++i) points.col(i) = u.Vector();
  const KdTree3 tree(points);
  std::vector<int> idx;
  std::vector<double> sq;
  for (int q = 0; q < 50; ++q) {
    const Eigen::Vector3d query = 1.1 * u.Vector();
    const double radius = 0.05 + 0.01 * q;
    tree.WithinRadius(query, radius, &idx, &sq);
    std::vector<int> expected;
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      if ((points.col(i) - query).squaredNorm() < radius * radius) {
        expected.push_back(static_cast<int>(i));
      }
    }
    ASSERT_EQ(idx.size(), sq.size());
    for (std::size_t k = 0; k < idx.size(); ++k) {
      EXPECT_DOUBLE_EQ(sq[k], (points.col(idx[k]) - query).squaredNorm());
    }
    std::sort(idx.begin(), idx.end());
    EXPECT_EQ(idx, expected) << "radius " << radius;
  }
  tree.WithinRadius(Eigen::Vector3d::Zero(), 0.0, &idx, &sq);
  EXPECT_TRUE(idx.empty());
}

TEST(SampleSurface, ReportsTheFaceOfEverySample) {
  const TriangleMesh mesh = Blob(Eigen::Vector3d(0, 0, 3), 6, 8);
  std::vector<int> faces;
  const Eigen::Matrix3Xd samples = SampleSurface(mesh, 3000, 6, &faces);
  EXPECT_EQ(samples, SampleSurface(mesh, 3000, 6));  // same stream with or without
  ASSERT_EQ(faces.size(), 3000u);
  for (int i = 0; i < 3000; ++i) {
    const int f = faces[static_cast<std::size_t>(i)];
    ASSERT_GE(f, 0);
    ASSERT_LT(f, mesh.NumFaces());
    const Eigen::Vector3d x = ClosestPointOnTriangle(
        samples.col(i), mesh.vertices.col(mesh.faces(0, f)), mesh.vertices.col(mesh.faces(1, f)),
        mesh.vertices.col(mesh.faces(2, f)));
    EXPECT_LT((x - samples.col(i)).norm(), 1e-12) << i;
  }
}

TEST(ShuffleColumns, IsADeterministicPermutation) {
  Eigen::Matrix3Xd points(3, 1000);
  for (int i = 0; i < 1000; ++i) points.col(i) = Eigen::Vector3d(i, 2 * i, 3 * i);
  const Eigen::Matrix3Xd a = ShuffleColumns(points, 4);
  EXPECT_EQ(a, ShuffleColumns(points, 4));
  EXPECT_NE(a, ShuffleColumns(points, 5));
  std::vector<int> seen(1000, 0);
  for (int i = 0; i < 1000; ++i) ++seen[static_cast<std::size_t>(a(0, i))];
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), 1000);
  EXPECT_NE(a, points);
}

TEST(RunIcpToSurface, UndoesARigidMotionOfSurfacePoints) {
  const TriangleMesh mesh = Blob(Eigen::Vector3d(0, 0, 3));
  const TriangleSurface3 surface(mesh);
  const Eigen::Matrix3d r = testing::Rotation(4.0, Eigen::Vector3d(1, 2, 0));
  const Eigen::Vector3d c(0, 0, 3), t(0.03, -0.02, 0.01);
  const Eigen::Matrix3Xd on = SampleSurface(mesh, 5000, 2);
  const Eigen::Matrix3Xd moved = (r * (on.colwise() - c)).colwise() + (c + t);
  IcpOptions options;
  options.max_queries = 2000;
  const IcpResult result = RunIcpToSurface(moved, surface, Similarity(), options);
  EXPECT_LT(result.final_rmse, 1e-6);
  const Eigen::Matrix3Xd back = result.source_to_target.Apply(moved);
  EXPECT_LT((back - on).colwise().norm().maxCoeff(), 1e-5);
  options.symmetric = true;
  EXPECT_THROW(RunIcpToSurface(moved, surface, Similarity(), options), InputError);
}

}  // namespace
}  // namespace banmo
