// The canonical-bounds refresh's check against the masks
// (optim/bounds_refresh.h), on the tiny quadruped (2 videos x 6 frames,
// object normalised to a half-extent of 1, exact root poses).
#include "banmo/optim/bounds_refresh.h"

#include <gtest/gtest.h>

#include "banmo/extract/extract.h"
#include "banmo/model/make_model.h"
#include "tiny_solver_scene.h"

namespace banmo {
namespace {

const Eigen::AlignedBox3d kStart(Eigen::Vector3d::Constant(-1.2), Eigen::Vector3d::Constant(1.2));

Eigen::AlignedBox3d Cube(double half) {
  return Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-half), Eigen::Vector3d::Constant(half));
}

// A model whose surface is its initial SDF sphere of this radius.
std::unique_ptr<Model> SphereModel(double radius) {
  ModelOptions options = testing::TinySolverConfig(StepRule::kAdam, 1).model;
  options.field.init_sphere_radius = radius;
  return MakeModelForDataset(testing::TinyQuadrupedDataset(), options);
}

TEST(MaskCoverage, CountsTheObjectPixelsWhoseRaysMeetTheBox) {
  const Dataset& data = testing::TinyQuadrupedDataset();
  const std::unique_ptr<Model> model = SphereModel(0.5);
  // The solver's starting box holds the whole object (half-extent 1; the
  // recentred origin lies within 0.1 of its centre, docs/solver.md).
  EXPECT_GE(MaskCoverage(data, *model, kStart), 0.999);
  // Nested boxes meet nested sets of rays.
  double previous = 0.0;
  for (double half : {0.05, 0.2, 0.4, 0.7, 1.2}) {
    const double coverage = MaskCoverage(data, *model, Cube(half));
    EXPECT_GE(coverage, previous) << half;
    previous = coverage;
  }
  // A box of a twentieth of the object's size meets few of its pixels; one
  // beside the object none.
  EXPECT_LT(MaskCoverage(data, *model, Cube(0.05)), 0.1);
  const Eigen::AlignedBox3d aside(Eigen::Vector3d(5, 5, -0.5), Eigen::Vector3d(6, 6, 0.5));
  EXPECT_EQ(MaskCoverage(data, *model, aside), 0.0);
  // The pixel stride samples the same fraction (to a few percent).
  EXPECT_NEAR(MaskCoverage(data, *model, Cube(0.4), 1), MaskCoverage(data, *model, Cube(0.4), 4),
              0.03);
}

// A fragment's box (the initial sphere of radius 0.3 stands for it; the
// calibrated sphere of a small network comes out at about 0.2) leaves most of
// the object pixels outside: the refresh keeps the box nearer the old one,
// so that it meets as many of them as the tolerance asks.
TEST(RefreshCanonicalBounds, HoldsTheBoxWhenTheSurfaceLosesTheMasks) {
  const Dataset& data = testing::TinyQuadrupedDataset();
  const std::unique_ptr<Model> model = SphereModel(0.3);
  const Eigen::AlignedBox3d surface = CanonicalBoundsFromSurface(*model, kStart);
  ASSERT_LT(surface.sizes().maxCoeff(), 0.6);

  const BoundsRefreshResult held = RefreshCanonicalBounds(*model, data, kStart, 0.05);
  EXPECT_TRUE(held.surface.isApprox(surface));
  EXPECT_GE(held.coverage_current, 0.999);
  EXPECT_LT(held.coverage_surface, 0.95);
  EXPECT_GT(held.kept, 0.0);
  EXPECT_LE(held.kept, 1.0);
  EXPECT_GE(held.coverage, 0.95);
  EXPECT_NEAR(held.coverage, MaskCoverage(data, *model, held.box), 1e-12);
  EXPECT_TRUE(held.box.contains(surface));
  EXPECT_TRUE(kStart.contains(held.box));

  // Bounds that already leave object pixels out (here a box of half the
  // object's size): the refresh leaves out no more than they do.
  const Eigen::AlignedBox3d partial = Cube(0.45);
  const double partial_coverage = MaskCoverage(data, *model, partial);
  ASSERT_LT(partial_coverage, 0.95);
  const BoundsRefreshResult from_partial = RefreshCanonicalBounds(*model, data, partial, 0.05);
  EXPECT_GT(from_partial.kept, 0.0);
  EXPECT_GE(from_partial.coverage, partial_coverage);
  EXPECT_TRUE(partial.contains(from_partial.box));

  // Without the check (>= 1) the surface's box, as before.
  const BoundsRefreshResult unchecked = RefreshCanonicalBounds(*model, data, kStart, 1.0);
  EXPECT_TRUE(unchecked.box.isApprox(surface));
  EXPECT_EQ(unchecked.kept, 0.0);
}

// A surface about the object's size (half-extent 1): its box is taken as
// it is.
TEST(RefreshCanonicalBounds, TakesASurfaceBoxThatKeepsTheMasks) {
  const Dataset& data = testing::TinyQuadrupedDataset();
  const std::unique_ptr<Model> model = SphereModel(0.9);
  const BoundsRefreshResult r = RefreshCanonicalBounds(*model, data, kStart, 0.05);
  EXPECT_EQ(r.kept, 0.0);
  EXPECT_TRUE(r.box.isApprox(CanonicalBoundsFromSurface(*model, kStart)));
  EXPECT_GE(r.coverage, 0.95);
  EXPECT_LT(r.box.volume(), kStart.volume());
}

}  // namespace
}  // namespace banmo
