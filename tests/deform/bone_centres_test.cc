#include "banmo/deform/bone_centres.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "../extract/mesh_test_util.h"
#include "banmo/util/error.h"

namespace banmo {
namespace {

using testing_util::WindingNumber;

// A closed latitude-longitude sphere (radius r, centre c), triangles
// counter-clockwise seen from outside.
TriangleMesh UvSphere(double r, const Eigen::Vector3d& c, int rings, int segments) {
  std::vector<Eigen::Vector3d> v = {c + Eigen::Vector3d(0, 0, r)};
  for (int i = 1; i < rings; ++i) {
    const double theta = M_PI * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * M_PI * j / segments;
      v.push_back(c + r * Eigen::Vector3d(std::sin(theta) * std::cos(phi),
                                          std::sin(theta) * std::sin(phi), std::cos(theta)));
    }
  }
  v.push_back(c - Eigen::Vector3d(0, 0, r));
  const int south = static_cast<int>(v.size()) - 1;
  auto at = [&](int ring, int j) { return 1 + (ring - 1) * segments + (j % segments); };
  std::vector<Eigen::Vector3i> f;
  for (int j = 0; j < segments; ++j) {
    f.emplace_back(0, at(1, j), at(1, j + 1));
    for (int i = 1; i + 1 < rings; ++i) {
      f.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      f.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
    f.emplace_back(at(rings - 1, j), south, at(rings - 1, j + 1));
  }
  TriangleMesh mesh;
  mesh.vertices.resize(3, static_cast<int>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) mesh.vertices.col(static_cast<int>(i)) = v[i];
  mesh.faces.resize(3, static_cast<int>(f.size()));
  for (size_t k = 0; k < f.size(); ++k) {
    Eigen::Vector3i t = f[k];
    const Eigen::Vector3d a = v[t[0]], b = v[t[1]], d = v[t[2]];
    if ((b - a).cross(d - a).dot((a + b + d) / 3.0 - c) < 0) std::swap(t[1], t[2]);
    mesh.faces.col(static_cast<int>(k)) = t;
  }
  return mesh;
}

TEST(BoneCentresFromSurface, CentresAreInsideAndDeterministic) {
  const Eigen::Vector3d centre(0.1, -0.2, 0.05);
  const TriangleMesh mesh = UvSphere(0.5, centre, 24, 48);
  ASSERT_NEAR(WindingNumber(mesh, centre), 1.0, 1e-9);  // a closed, outward mesh
  for (int B : {1, 8, 25}) {
    const auto centres = BoneCentresFromSurface(mesh, B, 7);
    ASSERT_EQ(static_cast<int>(centres.size()), B);
    for (const auto& c : centres) {
      EXPECT_NEAR(WindingNumber(mesh, c), 1.0, 1e-6) << c.transpose();
    }
    const auto again = BoneCentresFromSurface(mesh, B, 7);
    for (int b = 0; b < B; ++b) EXPECT_EQ(centres[b], again[b]);
    // Distinct centres.
    for (int a = 0; a < B; ++a) {
      for (int b = a + 1; b < B; ++b) EXPECT_GT((centres[a] - centres[b]).norm(), 1e-3);
    }
  }
  // One cluster: the area-weighted mean of a sphere is its centre (the
  // tessellation's asymmetry is far below this tolerance).
  EXPECT_LT((BoneCentresFromSurface(mesh, 1, 1)[0] - centre).norm(), 0.01);
  TriangleMesh tiny;
  tiny.vertices = Eigen::Matrix3Xd::Zero(3, 2);
  EXPECT_THROW(BoneCentresFromSurface(tiny, 3, 0), InputError);
}

}  // namespace
}  // namespace banmo
