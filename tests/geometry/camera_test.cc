#include "banmo/geometry/camera.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <Eigen/Core>

namespace banmo {
namespace {

TEST(PinholeCamera, ProjectInvertsRayDirection) {
  const Eigen::Vector4d k(500, 520, 128, 120);
  const Eigen::Vector2d uv(37.5, 200.25);
  Eigen::Vector3d dir;
  PixelToRayDirection(k.data(), uv.data(), dir.data());
  const Eigen::Vector3d x = 2.7 * dir;
  Eigen::Vector2d back;
  ProjectPoint(k.data(), x.data(), back.data());
  EXPECT_LT((back - uv).norm(), 1e-10);  // a few ulps of pixel coordinates ~1e2
}

TEST(PinholeCamera, BehindCameraIsFinite) {
  using J = ceres::Jet<double, 3>;
  const J k[4] = {J(500), J(500), J(100), J(100)};
  const J x[3] = {J(0.3, 0), J(-0.2, 1), J(-1.0, 2)};
  J uv[2];
  ProjectPoint(k, x, uv);
  EXPECT_TRUE(ceres::isfinite(uv[0]) && ceres::isfinite(uv[1]));
  EXPECT_EQ(uv[0].v[2], 0.0);  // clamped depth: no slope in z
}

TEST(PinholeCamera, Validity) {
  PinholeCamera cam;
  EXPECT_FALSE(cam.IsValid());
  cam.width = 64;
  cam.height = 48;
  cam.intrinsics << 50, 50, 32, 24;
  EXPECT_TRUE(cam.IsValid());
  cam.intrinsics[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(cam.IsValid());
}

}  // namespace
}  // namespace banmo
