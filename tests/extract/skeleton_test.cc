#include "banmo/extract/skeleton.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "../common/input_error.h"
#include "banmo/deform/bone_centres.h"
#include "banmo/extract/marching_cubes.h"

namespace banmo {
namespace {

// Distance from p to the segment [a, b].
double SegmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                       const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * d)).norm();
}

// A toy animal: a body capsule along x (radius 0.3) and four thin legs
// (radius 0.08, length 0.7) hanging from it, as the SDF of the union.
struct Animal {
  Eigen::Vector3d body_a{-0.7, 0.3, 0.0}, body_b{0.7, 0.3, 0.0};
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> legs = {
      {{0.55, 0.2, 0.18}, {0.55, -0.6, 0.18}},
      {{0.55, 0.2, -0.18}, {0.55, -0.6, -0.18}},
      {{-0.55, 0.2, 0.18}, {-0.55, -0.6, 0.18}},
      {{-0.55, 0.2, -0.18}, {-0.55, -0.6, -0.18}}};
  double Sdf(const Eigen::Vector3d& p) const {
    double d = SegmentDistance(p, body_a, body_b) - 0.3;
    for (const auto& [a, b] : legs) d = std::min(d, SegmentDistance(p, a, b) - 0.08);
    return d;
  }
  // Index of the leg whose axis is within `radius` of p, or -1.
  int LegOf(const Eigen::Vector3d& p, double radius) const {
    for (size_t k = 0; k < legs.size(); ++k) {
      if (p.y() < 0.0 && SegmentDistance(p, legs[k].first, legs[k].second) < radius) {
        return static_cast<int>(k);
      }
    }
    return -1;
  }
};

TriangleMesh AnimalMesh(const Animal& animal) {
  GridOptions grid;
  grid.resolution = 64;
  grid.bounds_min = Eigen::Vector3d(-1.2, -1.0, -0.7);
  grid.bounds_max = Eigen::Vector3d(1.2, 0.8, 0.7);
  return MarchingCubes(
      [&](const Eigen::Matrix3Xd& x, Eigen::VectorXd* v) {
        v->resize(x.cols());
        for (int i = 0; i < x.cols(); ++i) (*v)[i] = animal.Sdf(x.col(i));
      },
      grid);
}

TEST(CurveSkeleton, RunsAlongTheBodyAndEveryLeg) {
  const Animal animal;
  Eigen::Matrix3Xd from, to;
  CurveSkeleton(AnimalMesh(animal), &from, &to);
  ASSERT_GT(from.cols(), 0);
  // Every skeleton point lies inside the shape (the medial curves), and each
  // leg's lower half holds some of it.
  std::vector<int> leg_hits(animal.legs.size(), 0);
  for (int j = 0; j < from.cols(); ++j) {
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(from.col(j)), Eigen::Vector3d(to.col(j))}) {
      EXPECT_LT(animal.Sdf(p), 0.02) << p.transpose();  // one grid cell (0.0375) tolerance
      const int leg = animal.LegOf(p, 0.08);
      if (leg >= 0 && p.y() < -0.2) ++leg_hits[leg];
    }
  }
  for (size_t k = 0; k < leg_hits.size(); ++k) EXPECT_GT(leg_hits[k], 0) << "leg " << k;
}

// With 12 bones the surface's k-means spends most on the body (the legs have
// a small share of the area); along the skeleton every leg gets its own.
TEST(BoneCentresFromSkeleton, GivesEveryLegABone) {
  const Animal animal;
  const TriangleMesh mesh = AnimalMesh(animal);
  const std::vector<Eigen::Vector3d> skeleton = BoneCentresFromSkeleton(mesh, 12, 3);
  const std::vector<Eigen::Vector3d> surface = BoneCentresFromSurface(mesh, 12, 3);
  ASSERT_EQ(skeleton.size(), 12u);
  auto legs_with_bones = [&](const std::vector<Eigen::Vector3d>& centres) {
    std::vector<int> count(animal.legs.size(), 0);
    for (const Eigen::Vector3d& c : centres) {
      const int leg = animal.LegOf(c, 0.1);
      if (leg >= 0) ++count[leg];
    }
    return static_cast<int>(std::count_if(count.begin(), count.end(), [](int n) { return n > 0; }));
  };
  EXPECT_EQ(legs_with_bones(skeleton), 4);
  EXPECT_LT(legs_with_bones(surface), 4);
  for (const Eigen::Vector3d& c : skeleton) EXPECT_LT(animal.Sdf(c), 0.0) << c.transpose();
  // Repeatable up to the skeleton's own wobble: CGAL orders its edge
  // collapses by address, so a second call can differ by a fraction of a
  // grid cell (0.0375 here) and k-means then ends a little elsewhere, still
  // with a bone in every leg.
  const std::vector<Eigen::Vector3d> again = BoneCentresFromSkeleton(mesh, 12, 3);
  EXPECT_EQ(legs_with_bones(again), 4);
}

TEST(CurveSkeleton, RejectsAnOpenMesh) {
  TriangleMesh mesh;  // one triangle: not closed
  mesh.vertices.resize(3, 3);
  mesh.vertices << 0, 1, 0, 0, 0, 1, 0, 0, 0;
  mesh.faces.resize(3, 1);
  mesh.faces << 0, 1, 2;
  Eigen::Matrix3Xd from, to;
  const std::string error = testing::ErrorOf([&] { CurveSkeleton(mesh, &from, &to); });
  EXPECT_NE(error.find("not closed"), std::string::npos) << error;
  EXPECT_THROW(BoneCentresFromSkeleton(mesh, 2, 0), InputError);
}

}  // namespace
}  // namespace banmo
