#include "banmo/eval/metrics.h"

#include <gtest/gtest.h>

#include "banmo/eval/surface_sampling.h"
#include "banmo/util/error.h"
#include "test_shapes.h"

namespace banmo {
namespace {

TEST(ComputeDistanceMetrics, HandComputedValues) {
  Eigen::VectorXd pred_to_gt(4);
  pred_to_gt << 0.0, 0.01, 0.03, 0.2;  // mean 0.06
  Eigen::VectorXd gt_to_pred(2);
  gt_to_pred << 0.015, 0.045;  // mean 0.03
  // longest edge 2: tau = 0.02, 0.04, 0.1.
  const DistanceMetrics m = ComputeDistanceMetrics(pred_to_gt, gt_to_pred, 2.0);
  EXPECT_DOUBLE_EQ(m.pred_to_gt, 0.06);
  EXPECT_DOUBLE_EQ(m.gt_to_pred, 0.03);
  EXPECT_DOUBLE_EQ(m.chamfer_sum, 0.09);
  EXPECT_DOUBLE_EQ(m.chamfer_mean, 0.045);
  EXPECT_DOUBLE_EQ(m.thresholds[0], 0.02);
  EXPECT_DOUBLE_EQ(m.precision[0], 0.5);  // 0, 0.01
  EXPECT_DOUBLE_EQ(m.recall[0], 0.5);     // 0.015
  EXPECT_DOUBLE_EQ(m.fscore[0], 0.5);
  EXPECT_DOUBLE_EQ(m.precision[1], 0.75);  // 0, 0.01, 0.03
  EXPECT_DOUBLE_EQ(m.recall[1], 0.5);      // 0.045 > 0.04
  EXPECT_DOUBLE_EQ(m.fscore[1], 2 * 0.75 * 0.5 / 1.25);
  EXPECT_DOUBLE_EQ(m.precision[2], 0.75);  // 0.2 > 0.1
  EXPECT_DOUBLE_EQ(m.recall[2], 1.0);
}

TEST(ComputeDistanceMetrics, StrictThresholdAndZeroFscore) {
  Eigen::VectorXd d(1);
  d << 0.02;  // exactly tau_1 = 0.01 * 2: not matched (d < tau is strict)
  const DistanceMetrics m = ComputeDistanceMetrics(d, d, 2.0);
  EXPECT_EQ(m.fscore[0], 0.0);
  EXPECT_EQ(m.fscore[1], 1.0);
}

TEST(SampleSurface, UniformByAreaAndDeterministic) {
  // Two triangles: the second has 3x the area of the first.
  TriangleMesh mesh;
  mesh.vertices.resize(3, 6);
  mesh.vertices << 0, 1, 0, 10, 13, 10,  //
      0, 0, 1, 0, 0, 1,                  //
      0, 0, 0, 0, 0, 0;
  mesh.faces.resize(3, 2);
  mesh.faces << 0, 3, 1, 4, 2, 5;
  EXPECT_DOUBLE_EQ(MeshArea(mesh), 0.5 + 1.5);
  const Eigen::Matrix3Xd s = SampleSurface(mesh, 40000, 42);
  const double second = static_cast<double>((s.row(0).array() >= 10.0).count()) / 40000.0;
  // Binomial(40000, 0.75): sd = 0.0022; 5 sd.
  EXPECT_NEAR(second, 0.75, 0.011);
  // Points lie in their triangles: x + y <= 1 for the first (x - 10) / 3 + y <= 1 for the second.
  for (int i = 0; i < s.cols(); ++i) {
    const double x = s(0, i) >= 10.0 ? (s(0, i) - 10.0) / 3.0 : s(0, i);
    EXPECT_GE(x, 0.0);
    EXPECT_GE(s(1, i), 0.0);
    EXPECT_LE(x + s(1, i), 1.0 + 1e-12);
  }
  EXPECT_EQ(SampleSurface(mesh, 100, 42), SampleSurface(mesh, 100, 42));
  EXPECT_NE(SampleSurface(mesh, 100, 42), SampleSurface(mesh, 100, 43));
}

TEST(SampleSurface, NoAreaIsAnError) {
  TriangleMesh mesh;
  mesh.vertices = Eigen::Matrix3Xd::Zero(3, 3);
  mesh.faces.resize(3, 1);
  mesh.faces << 0, 1, 2;
  EXPECT_THROW(SampleSurface(mesh, 10, 0), InputError);
}

}  // namespace
}  // namespace banmo
