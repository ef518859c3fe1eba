#include "banmo/extract/marching_cubes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "banmo/extract/extract.h"
#include "banmo/util/error.h"
#include "mesh_test_util.h"

namespace banmo {
namespace {

using testing_util::CountNonManifoldVertices;

FieldBatchFunction SphereSdf(const Eigen::Vector3d& centre, double radius) {
  return [=](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
    *f = (x.colwise() - centre).colwise().norm().transpose().array() - radius;
  };
}

// Torus around the z axis: major radius R, minor radius r.
double TorusSdf(const Eigen::Vector3d& p, double R, double r) {
  const double q = std::hypot(p.x(), p.y()) - R;
  return std::hypot(q, p.z()) - r;
}

GridOptions Grid(int resolution) {
  GridOptions g;
  g.resolution = resolution;
  return g;
}

TEST(MarchingCubes, SphereIsClosedOrientedGenusZeroAndAccurate) {
  const double r = 0.6;
  const GridOptions grid = Grid(48);
  const double h = 2.0 / 48;
  const TriangleMesh mesh = MarchingCubes(SphereSdf(Eigen::Vector3d::Zero(), r), grid);
  ASSERT_GT(mesh.NumFaces(), 1000);
  const MeshStats s = ComputeMeshStats(mesh);
  EXPECT_TRUE(s.IsClosedOriented())
      << s.num_boundary_edges << " " << s.num_nonmanifold_edges << " " << s.num_inconsistent_edges;
  EXPECT_EQ(CountNonManifoldVertices(mesh), 0);
  EXPECT_EQ(s.num_components, 1);
  EXPECT_EQ(s.euler_characteristic, 2);
  EXPECT_EQ(s.num_vertices, mesh.NumVertices());  // no unreferenced vertices
  // Linear interpolation of |X| - r along an edge: the root is off by at
  // most about h^2 / (2 r) = 0.0015 = 0.035 h (chord of the level set);
  // measured 0.009 h.
  double max_error = 0.0;
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    max_error = std::max(max_error, std::abs(mesh.vertices.col(i).norm() - r));
  }
  EXPECT_LT(max_error, 0.05 * h);
  // An inscribed polyhedron: the volume is a little low, by O((h/r)^2);
  // measured -0.29 % (area -0.15 %).
  const double volume = 4.0 / 3.0 * M_PI * r * r * r;
  EXPECT_NEAR(s.signed_volume, volume, 0.01 * volume);
  EXPECT_NEAR(s.area, 4 * M_PI * r * r, 0.01 * 4 * M_PI * r * r);
  // Outward normals: every face's normal points away from the centre.
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, f));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, f));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, f));
    ASSERT_GT((b - a).cross(c - a).dot(a + b + c), 0.0) << "face " << f;
  }
}

TEST(MarchingCubes, TorusHasEulerCharacteristicZero) {
  const double R = 0.5, r = 0.2;
  GridOptions grid = Grid(64);
  const double h = 2.0 / 64;
  const TriangleMesh mesh = MarchingCubes(
      [&](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
        f->resize(x.cols());
        for (int i = 0; i < x.cols(); ++i) (*f)[i] = TorusSdf(x.col(i), R, r);
      },
      grid);
  const MeshStats s = ComputeMeshStats(mesh);
  EXPECT_TRUE(s.IsClosedOriented());
  EXPECT_EQ(CountNonManifoldVertices(mesh), 0);
  EXPECT_EQ(s.num_components, 1);
  EXPECT_EQ(s.euler_characteristic, 0);
  double max_error = 0.0;
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    max_error = std::max(max_error, std::abs(TorusSdf(mesh.vertices.col(i), R, r)));
  }
  // Minor radius 0.2 = 6.4 h: interpolation error at most about
  // h^2 / (2 r) = 0.08 h; measured 0.019 h.
  EXPECT_LT(max_error, 0.1 * h);
  const double volume = 2 * M_PI * M_PI * R * r * r;
  EXPECT_NEAR(s.signed_volume, volume, 0.02 * volume);  // measured -0.51 %
}

// Ambiguous faces and cells: random node values (a rough field with many
// saddles) must still give a closed, consistently oriented 2-manifold, which
// only holds if both cells of every face resolve it the same way.
TEST(MarchingCubes, RandomFieldGivesClosedOrientedManifold) {
  for (uint32_t seed = 1; seed <= 50; ++seed) {
    GridOptions grid = Grid(10);
    grid.coarse_stride = 1;  // dense: the field is not Lipschitz
    auto hash_field = [seed](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
      f->resize(x.cols());
      for (int i = 0; i < x.cols(); ++i) {
        // Value from the node's integer coordinates (grid spacing 0.2).
        const auto q = ((x.col(i).array() + 1.0) * 5.0).round().cast<int64_t>();
        uint64_t k = seed * 0x9E3779B97F4A7C15ull ^ (q[0] * 73856093ll) ^ (q[1] * 19349663ll) ^
                     (q[2] * 83492791ll);
        k ^= k >> 33;
        k *= 0xff51afd7ed558ccdull;
        k ^= k >> 33;
        (*f)[i] = static_cast<double>(k % 1000) / 1000.0 - 0.5;
      }
    };
    const TriangleMesh mesh = MarchingCubes(hash_field, grid);
    ASSERT_GT(mesh.NumFaces(), 0);
    const MeshStats s = ComputeMeshStats(mesh);
    EXPECT_TRUE(s.IsClosedOriented()) << "seed " << seed;
    EXPECT_EQ(CountNonManifoldVertices(mesh), 0) << "seed " << seed;
    // Closed orientable surfaces: Euler characteristic = 2 (components - genus).
    EXPECT_EQ((2 * s.num_components - s.euler_characteristic) % 2, 0) << "seed " << seed;
    EXPECT_GT(s.signed_volume, 0.0) << "seed " << seed;  // outward overall
  }
}

// Every one of the 256 corner configurations: nodes at -1, 0, 1, 2 per axis;
// the cell [0,1]^3 in the middle takes the configuration, every other node is
// outside. The inside corners are then enclosed by the surrounding cells, so
// the surface must be closed, consistently oriented, vertex-manifold, with
// positive volume and genus 0 per component (the inside sets of one cell
// cannot form a handle).
TEST(MarchingCubes, AllCornerConfigurationsGiveClosedOrientedSurfaces) {
  for (int config = 1; config < 256; ++config) {
    GridOptions grid = Grid(3);
    grid.coarse_stride = 1;
    grid.close_at_bounds = false;
    grid.bounds_min.setConstant(-1.0);
    grid.bounds_max.setConstant(2.0);
    auto field = [config](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
      f->resize(x.cols());
      for (int i = 0; i < x.cols(); ++i) {
        const Eigen::Vector3i q = x.col(i).array().round().cast<int>();
        (*f)[i] = 1.0;
        if ((q.array() >= 0).all() && (q.array() <= 1).all()) {
          const int c = q.x() + 2 * q.y() + 4 * q.z();
          // Distinct magnitudes so vertices are not all at edge midpoints.
          if ((config >> c) & 1) (*f)[i] = -0.3 - 0.1 * c;
        }
      }
    };
    const TriangleMesh mesh = MarchingCubes(field, grid);
    const MeshStats s = ComputeMeshStats(mesh);
    EXPECT_TRUE(s.IsClosedOriented()) << "config " << config;
    EXPECT_EQ(CountNonManifoldVertices(mesh), 0) << "config " << config;
    EXPECT_EQ(s.euler_characteristic, 2 * s.num_components) << "config " << config;
    EXPECT_GT(s.signed_volume, 0.0) << "config " << config;
  }
}

TEST(MarchingCubes, TwoSpheresAndLargestComponent) {
  const Eigen::Vector3d c1(-0.45, 0, 0), c2(0.5, 0.1, 0);
  auto two = [&](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
    Eigen::VectorXd a, b;
    SphereSdf(c1, 0.35)(x, &a);
    SphereSdf(c2, 0.25)(x, &b);
    *f = a.cwiseMin(b);
  };
  TriangleMesh mesh = MarchingCubes(two, Grid(48));
  const MeshStats s = ComputeMeshStats(mesh);
  EXPECT_TRUE(s.IsClosedOriented());
  EXPECT_EQ(s.num_components, 2);
  EXPECT_EQ(s.euler_characteristic, 4);
  // Colours follow their vertices through the filter.
  mesh.colors.resize(3, mesh.NumVertices());
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    mesh.colors.col(i).setConstant(mesh.vertices(0, i) < 0 ? 10 : 200);
  }
  const TriangleMesh big = KeepLargestComponent(mesh);
  const MeshStats sb = ComputeMeshStats(big);
  EXPECT_TRUE(sb.IsClosedOriented());
  EXPECT_EQ(sb.num_components, 1);
  EXPECT_EQ(sb.euler_characteristic, 2);
  EXPECT_EQ(sb.num_vertices, big.NumVertices());
  ASSERT_TRUE(big.HasColors());
  for (int i = 0; i < big.NumVertices(); ++i) {
    ASSERT_NEAR((big.vertices.col(i) - c1).norm(), 0.35, 0.01);
    ASSERT_EQ(big.colors(0, i), 10);
  }
  EXPECT_NEAR(sb.signed_volume, 4.0 / 3.0 * M_PI * std::pow(0.35, 3), 0.02 * 0.18);
}

// A body, a detached part (about a tenth of the body's faces, like a wing
// or leg the zero level set separates from it) and a floater (a speck of a
// few faces, under 0.1 %): KeepLargeComponents keeps the components at or
// above the fraction.
TEST(MarchingCubes, LargeComponentsKeepDetachedPartsAndDropFloaters) {
  // The floater's centre is a grid node (-1 + 104 * 2 / 128), so it has a
  // node inside however small it is.
  const Eigen::Vector3d body(-0.3, 0, 0), part(0.6, 0, 0), floater(0.625, 0.625, 0.625);
  auto three = [&](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
    Eigen::VectorXd a, b, c;
    SphereSdf(body, 0.6)(x, &a);
    SphereSdf(part, 0.2)(x, &b);
    SphereSdf(floater, 0.012)(x, &c);
    *f = a.cwiseMin(b).cwiseMin(c);
  };
  const TriangleMesh mesh = MarchingCubes(three, Grid(128));
  ASSERT_EQ(ComputeMeshStats(mesh).num_components, 3);
  auto components = [](const TriangleMesh& m) { return ComputeMeshStats(m).num_components; };
  // Faces scale with the area: the part has about (0.2 / 0.6)^2 = 11 % of
  // the body's, the floater a handful of faces (a sphere under a cell).
  EXPECT_EQ(components(KeepLargeComponents(mesh, 0.0)), 3);
  EXPECT_EQ(KeepLargeComponents(mesh, 0.0).NumFaces(), mesh.NumFaces());
  const TriangleMesh kept = KeepLargeComponents(mesh, kDefaultMinComponentFraction);
  EXPECT_EQ(components(kept), 2);
  EXPECT_EQ(components(KeepLargeComponents(mesh, 0.01)), 2);
  EXPECT_EQ(components(KeepLargeComponents(mesh, 0.05)), 2);
  EXPECT_EQ(components(KeepLargeComponents(mesh, 0.2)), 1);
  const TriangleMesh largest = KeepLargestComponent(mesh);
  const TriangleMesh one = KeepLargeComponents(mesh, 1.0);
  EXPECT_EQ(one.faces, largest.faces);
  EXPECT_EQ(one.vertices, largest.vertices);
  // The default keeps body and part whole: every kept vertex lies on one of
  // the two spheres (within a cell), none near the floater.
  for (int i = 0; i < kept.NumVertices(); ++i) {
    const Eigen::Vector3d v = kept.vertices.col(i);
    const double d = std::min(std::abs((v - body).norm() - 0.6), std::abs((v - part).norm() - 0.2));
    ASSERT_LT(d, 2.0 / 128) << v.transpose();
  }
  EXPECT_EQ(KeepLargeComponents(TriangleMesh(), 0.5).NumFaces(), 0);
}

TEST(MarchingCubes, SurfaceLeavingTheBoxIsCappedOrOpen) {
  // Sphere of radius 1.2 centred in [-1,1]^3: it crosses the box faces.
  GridOptions grid = Grid(24);
  const TriangleMesh capped = MarchingCubes(SphereSdf(Eigen::Vector3d::Zero(), 1.2), grid);
  const MeshStats sc = ComputeMeshStats(capped);
  EXPECT_TRUE(sc.IsClosedOriented());
  EXPECT_EQ(sc.euler_characteristic, 2);
  // Capped within one cell of the box: all vertices inside the box.
  EXPECT_LE(capped.vertices.cwiseAbs().maxCoeff(), 1.0);
  grid.close_at_bounds = false;
  const TriangleMesh open = MarchingCubes(SphereSdf(Eigen::Vector3d::Zero(), 1.2), grid);
  const MeshStats so = ComputeMeshStats(open);
  EXPECT_GT(so.num_boundary_edges, 0);
  EXPECT_EQ(so.num_nonmanifold_edges, 0);
  EXPECT_EQ(so.num_inconsistent_edges, 0);
}

TEST(MarchingCubes, BatchingAndAnisotropicBoundsAndIsoLevel) {
  GridOptions grid = Grid(20);
  grid.bounds_min = Eigen::Vector3d(-1.0, -0.5, -0.8);
  grid.bounds_max = Eigen::Vector3d(1.0, 0.5, 0.8);
  const GridShape shape = ComputeGridShape(grid);
  EXPECT_EQ(shape.cells, Eigen::Vector3i(20, 10, 16));
  EXPECT_NEAR(shape.spacing.x(), 0.1, 1e-15);
  const auto sphere = SphereSdf(Eigen::Vector3d(0.1, 0, 0), 0.3);
  const TriangleMesh a = MarchingCubes(sphere, grid);
  grid.max_batch_points = 7;  // many small batches: same result
  int calls = 0;
  const TriangleMesh b = MarchingCubes(
      [&](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
        EXPECT_LE(x.cols(), 7);
        ++calls;
        sphere(x, f);
      },
      grid);
  EXPECT_GT(calls, 100);
  ASSERT_EQ(a.NumVertices(), b.NumVertices());
  ASSERT_EQ(a.NumFaces(), b.NumFaces());
  EXPECT_EQ((a.vertices - b.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_TRUE((a.faces.array() == b.faces.array()).all());
  // Iso level 0.1: the sphere of radius 0.4.
  grid.iso_level = 0.1;
  const TriangleMesh c = MarchingCubes(sphere, grid);
  for (int i = 0; i < c.NumVertices(); ++i) {
    ASSERT_NEAR((c.vertices.col(i) - Eigen::Vector3d(0.1, 0, 0)).norm(), 0.4, 0.01);
  }
}

void ExpectSameMesh(const TriangleMesh& a, const TriangleMesh& b, double tolerance) {
  ASSERT_EQ(a.NumVertices(), b.NumVertices());
  ASSERT_EQ(a.NumFaces(), b.NumFaces());
  if (a.NumVertices() == 0) return;
  EXPECT_LE((a.vertices - b.vertices).cwiseAbs().maxCoeff(), tolerance);
  EXPECT_TRUE((a.faces.array() == b.faces.array()).all());
}

// Coarse-to-fine sampling gives the dense result for SDFs (1-Lipschitz),
// with far fewer evaluations, including a feature smaller than a block.
TEST(MarchingCubes, CoarseToFineEqualsDenseForSdfs) {
  const Eigen::Vector3d c1(-0.45, 0, 0), c2(0.5, 0.1, 0), c3(0.31, -0.62, 0.44);
  auto field = [&](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
    Eigen::VectorXd a, b, c;
    SphereSdf(c1, 0.35)(x, &a);
    SphereSdf(c2, 0.25)(x, &b);
    SphereSdf(c3, 0.04)(x, &c);  // 1.3 cells across, inside one 4-cell block
    f->resize(x.cols());
    for (int i = 0; i < x.cols(); ++i) {
      const Eigen::Vector3d below = x.col(i) - Eigen::Vector3d(0, 0, -0.6);
      (*f)[i] = std::min({a[i], b[i], c[i], TorusSdf(below, 0.6, 0.1)});
    }
  };
  for (bool close : {true, false}) {
    GridOptions dense = Grid(64);
    dense.coarse_stride = 1;
    dense.close_at_bounds = close;
    MarchingCubesStats dense_stats, coarse_stats;
    const TriangleMesh a = MarchingCubes(field, dense, &dense_stats);
    EXPECT_EQ(dense_stats.num_evaluated, close ? 63 * 63 * 63 : 65 * 65 * 65);
    EXPECT_EQ(ComputeMeshStats(a).num_components, 4);
    for (int stride : {2, 4, 7}) {
      GridOptions coarse = dense;
      coarse.coarse_stride = stride;
      const TriangleMesh b = MarchingCubes(field, coarse, &coarse_stats);
      ExpectSameMesh(a, b, 0.0);
      EXPECT_EQ(coarse_stats.num_nodes, 65 * 65 * 65);
      if (stride == 4 && close) {
        // Measured 52 % at this coarse resolution with four shapes (the band
        // is about 7 cells thick on each side); 8 % for one sphere at 256
        // (benchmarks/extract).
        EXPECT_LT(coarse_stats.num_evaluated, 0.6 * dense_stats.num_evaluated);
      }
    }
  }
}

TEST(MarchingCubes, EmptyLevelSetGivesEmptyMesh) {
  const TriangleMesh mesh = MarchingCubes(SphereSdf(Eigen::Vector3d(5, 5, 5), 0.5), Grid(8));
  EXPECT_EQ(mesh.NumVertices(), 0);
  EXPECT_EQ(mesh.NumFaces(), 0);
  EXPECT_EQ(KeepLargestComponent(mesh).NumFaces(), 0);
}

TEST(MarchingCubes, BadOptionsAndNonFiniteFieldThrow) {
  GridOptions g = Grid(1);
  EXPECT_THROW(g.Check(), InputError);
  g = Grid(8);
  g.bounds_max.x() = -2.0;
  try {
    g.Check();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("grid.bounds"), std::string::npos) << e.what();
  }
  g = Grid(8);
  g.max_batch_points = 0;
  EXPECT_THROW(g.Check(), InputError);
  auto nan_field = [](const Eigen::Matrix3Xd& x, Eigen::VectorXd* f) {
    f->setConstant(x.cols(), std::nan(""));
  };
  EXPECT_THROW(MarchingCubes(nan_field, Grid(8)), InputError);
}

}  // namespace
}  // namespace banmo
