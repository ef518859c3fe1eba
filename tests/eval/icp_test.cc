#include "banmo/eval/icp.h"

#include <gtest/gtest.h>

#include <random>

#include "banmo/eval/surface_sampling.h"
#include "banmo/util/error.h"
#include "test_shapes.h"

namespace banmo {
namespace {

using testing::Blob;
using testing::Rotation;

TEST(EstimateSimilarity, RecoversExactSimilarity) {
  std::mt19937 rng(1);
  std::normal_distribution<double> gauss;
  Eigen::Matrix3Xd x(3, 50);
  for (int i = 0; i < 50; ++i) x.col(i) << gauss(rng), gauss(rng), gauss(rng);
  const Eigen::Matrix3d r = Rotation(73.0, Eigen::Vector3d(1, -2, 0.5));
  const Eigen::Vector3d t(0.3, -4.0, 2.0);
  const Eigen::Matrix3Xd y = ((1.7 * r) * x).colwise() + t;
  const Similarity est = EstimateSimilarity(x, y, Eigen::VectorXd(), true);
  // Closed form on exact data: only rounding error (~1e-15 relative).
  EXPECT_NEAR(est.scale, 1.7, 1e-12);
  EXPECT_LT((est.rotation - r).norm(), 1e-12);
  EXPECT_LT((est.translation - t).norm(), 1e-12);
  // Rigid estimate of rigidly moved points.
  const Eigen::Matrix3Xd y_rigid = (r * x).colwise() + t;
  const Similarity rigid = EstimateSimilarity(x, y_rigid, Eigen::VectorXd(), false);
  EXPECT_EQ(rigid.scale, 1.0);
  EXPECT_LT((rigid.rotation - r).norm(), 1e-12);
}

TEST(EstimateSimilarity, ZeroWeightsIgnoreOutliersAndNoReflection) {
  std::mt19937 rng(2);
  std::normal_distribution<double> gauss;
  Eigen::Matrix3Xd x(3, 40);
  for (int i = 0; i < 40; ++i) x.col(i) << gauss(rng), gauss(rng), gauss(rng);
  const Eigen::Matrix3d r = Rotation(20.0, Eigen::Vector3d(0, 0, 1));
  Eigen::Matrix3Xd y = (r * x).colwise() + Eigen::Vector3d(1, 2, 3);
  Eigen::VectorXd w = Eigen::VectorXd::Ones(40);
  for (int i = 0; i < 10; ++i) {
    y.col(i) += Eigen::Vector3d(50, -30, 10);  // outliers with weight 0
    w(i) = 0.0;
  }
  const Similarity est = EstimateSimilarity(x, y, w, true);
  EXPECT_NEAR(est.scale, 1.0, 1e-12);
  EXPECT_LT((est.rotation - r).norm(), 1e-12);
  // A mirrored target: the best proper rotation is returned (det = +1).
  Eigen::Matrix3Xd mirrored = x;
  mirrored.row(0) *= -1.0;
  const Similarity proper = EstimateSimilarity(x, mirrored, Eigen::VectorXd(), true);
  EXPECT_NEAR(proper.rotation.determinant(), 1.0, 1e-12);
  EXPECT_GT(proper.scale, 0.0);
}

// Similarity ICP on surface samples of a blob moved by a known similarity.
struct IcpCase {
  Eigen::Matrix3Xd source;
  Eigen::Matrix3Xd target;
};

IcpCase MakeCase(double degrees, double scale, const Eigen::Vector3d& t) {
  const TriangleMesh blob = Blob(Eigen::Vector3d::Zero());
  const Eigen::Matrix3Xd target = SampleSurface(blob, 4000, 5);
  const Eigen::Matrix3Xd source =
      ((scale * Rotation(degrees, Eigen::Vector3d(1, 2, 3))) * target).colwise() + t;
  return {source, target};
}

TEST(RunIcp, RecoversSimilarityFromCentroidStart) {
  const IcpCase c = MakeCase(25.0, 1.6, Eigen::Vector3d(0.5, -0.2, 0.3));
  const KdTree3 source(c.source);
  const KdTree3 target(c.target);
  // Start with matching centroids and RMS radii, rotation unknown.
  const Eigen::Vector3d cs = c.source.rowwise().mean();
  const Eigen::Vector3d ct = c.target.rowwise().mean();
  Similarity init;
  init.scale = 1.0 / 1.6;
  init.translation = ct - init.scale * cs;
  for (const bool symmetric : {false, true}) {
    IcpOptions options;
    options.estimate_scale = true;
    options.symmetric = symmetric;
    const IcpResult result = RunIcp(source, target, init, options);
    EXPECT_TRUE(result.converged);
    EXPECT_LT(result.final_rmse, 1e-9);  // exact correspondences are reached
    EXPECT_NEAR(result.source_to_target.scale, 1.0 / 1.6, 1e-9);
    EXPECT_LT((result.source_to_target.Apply(c.source) - c.target).cwiseAbs().maxCoeff(), 1e-8);
    EXPECT_LT(result.final_rmse, result.initial_rmse);
  }
}

TEST(RunIcp, ScaleGuardStopsCollapse) {
  // A tiny source cluster near one end of a large target: one-sided
  // similarity ICP shrinks the source onto the nearest target points.
  // The guard keeps the scale within [s0 / k, s0 * k].
  const IcpCase c = MakeCase(0.0, 1.0, Eigen::Vector3d::Zero());
  const KdTree3 source(c.source);
  const KdTree3 target(c.target);
  Similarity init;
  init.scale = 0.05;
  init.translation = Eigen::Vector3d(1.5, 0.0, 0.0);
  IcpOptions options;
  options.estimate_scale = true;
  options.max_scale_change = 2.0;
  const IcpResult result = RunIcp(source, target, init, options);
  EXPECT_GE(result.source_to_target.scale, 0.05 / 2.0 - 1e-15);
  EXPECT_LE(result.source_to_target.scale, 0.05 * 2.0 + 1e-15);
  // Without the guard (k huge) the scale shrinks below the guarded bound.
  options.max_scale_change = 1e9;
  const IcpResult free = RunIcp(source, target, init, options);
  EXPECT_LT(free.source_to_target.scale, 0.05 / 2.0);
  EXPECT_TRUE(result.scale_clamped);
}

TEST(RunIcp, TrimmedAndHuberResistOutliers) {
  // 10 % of the source points are far outliers; rigid ICP with all points is
  // pulled off, the robust variants recover the motion.
  IcpCase c = MakeCase(8.0, 1.0, Eigen::Vector3d(0.05, 0.02, -0.03));
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (Eigen::Index i = 0; i < c.source.cols(); i += 10) {
    c.source.col(i) = Eigen::Vector3d(uni(rng), uni(rng), uni(rng)) + Eigen::Vector3d(4, 4, 0);
  }
  const KdTree3 source(c.source);
  const KdTree3 target(c.target);
  auto inlier_error = [&](const IcpResult& r) {
    double worst = 0.0;
    const Eigen::Matrix3Xd moved = r.source_to_target.Apply(c.source);
    for (Eigen::Index i = 0; i < c.source.cols(); ++i) {
      if (i % 10 != 0) worst = std::max(worst, (moved.col(i) - c.target.col(i)).norm());
    }
    return worst;
  };
  IcpOptions options;
  const double plain = inlier_error(RunIcp(source, target, Similarity(), options));
  options.robust = RobustLoss::kTrimmed;
  options.trim_fraction = 0.85;
  const double trimmed = inlier_error(RunIcp(source, target, Similarity(), options));
  options.robust = RobustLoss::kHuber;
  const double huber = inlier_error(RunIcp(source, target, Similarity(), options));
  EXPECT_GT(plain, 0.05);    // pulled off by about the outliers' leverage
  EXPECT_LT(trimmed, 1e-6);  // outliers dropped: exact correspondences found
  EXPECT_LT(huber, 0.5 * plain);
}

TEST(IcpOptions, CheckNamesTheField) {
  IcpOptions options;
  options.trim_fraction = 0.0;
  try {
    options.Check();
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("trim_fraction"), std::string::npos);
  }
  EXPECT_THROW(ParseRobustLoss("tukey"), InputError);
  EXPECT_EQ(ParseRobustLoss("huber"), RobustLoss::kHuber);
}

}  // namespace
}  // namespace banmo
