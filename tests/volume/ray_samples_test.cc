// volume/ray_samples.h: near/far planes, ray direction length, importance
// resampling.
#include "banmo/volume/ray_samples.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace banmo {
namespace {

// The pose camera_from_root with rotation q (w, x, y, z) and translation t.
Pose MakePose(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
  Pose p;
  p << q.w(), q.x(), q.y(), q.z(), t.x(), t.y(), t.z();
  return p;
}

TEST(NearFarPlanes, BoxInFrontOfTheCameraWidenedByTheMargin) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1));
  double near = 0, far = 0;
  NearFarPlanes(MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 5)), box, 0.2, &near,
                &far);
  EXPECT_NEAR(near, 4 * 0.8, 1e-12);
  EXPECT_NEAR(far, 6 * 1.2, 1e-12);
  NearFarPlanes(MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 5)), box, 0.0, &near,
                &far);
  EXPECT_NEAR(near, 4, 1e-12);
  EXPECT_NEAR(far, 6, 1e-12);
}

TEST(NearFarPlanes, FollowsTheRotatedBox) {
  // A long box along x turned 90 degrees about y: its x extent becomes depth.
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-2, -0.5, -0.5), Eigen::Vector3d(2, 0.5, 0.5));
  const Eigen::Quaterniond q(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()));
  double near = 0, far = 0;
  NearFarPlanes(MakePose(q, Eigen::Vector3d(0, 0, 10)), box, 0.0, &near, &far);
  EXPECT_NEAR(near, 8, 1e-9);
  EXPECT_NEAR(far, 12, 1e-9);
  NearFarPlanes(MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 10)), box, 0.0,
                &near, &far);
  EXPECT_NEAR(near, 9.5, 1e-12);
  EXPECT_NEAR(far, 10.5, 1e-12);
}

TEST(NearFarPlanes, NearStaysInFrontOfACameraInsideTheBox) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1));
  double near = 0, far = 0;
  NearFarPlanes(MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()), box, 0.2, &near,
                &far);
  EXPECT_DOUBLE_EQ(near, 1e-3);
  EXPECT_NEAR(far, 1.2, 1e-12);
  // A box wholly behind the camera: far is still beyond near.
  NearFarPlanes(MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -5)), box, 0.2,
                &near, &far);
  EXPECT_DOUBLE_EQ(near, 1e-3);
  EXPECT_DOUBLE_EQ(far, near + 1e-3);
}

TEST(RayDirectionLength, OneAtThePrincipalPointAndGrowingOutwards) {
  const Eigen::Vector4d k(100, 50, 32, 24);  // fx, fy, cx, cy
  EXPECT_DOUBLE_EQ(RayDirectionLength(k, Eigen::Vector2d(32, 24)), 1.0);
  EXPECT_NEAR(RayDirectionLength(k, Eigen::Vector2d(132, 24)), std::sqrt(2.0), 1e-15);
  EXPECT_NEAR(RayDirectionLength(k, Eigen::Vector2d(32, -26)), std::sqrt(2.0), 1e-15);
  EXPECT_NEAR(RayDirectionLength(k, Eigen::Vector2d(82, 49)), std::sqrt(1.5), 1e-15);
}

TEST(ImportanceResample, KeepsTheStratifiedSamplesAndDrawsWhereTheWeightIs) {
  // added 0: the even samples kept, the odd half redrawn; added K: every
  // sample kept and K drawn.
  for (const int added : {0, 24}) {
    std::mt19937 rng(3);
    const int n = 16;
    const double dir_norm = 1.25;
    RaySamples s = StratifiedSamples(n, 2.0, 6.0, dir_norm, /*jitter=*/true, &rng);
    const RaySamples before = s;
    // All the weight on interval 5.
    std::vector<double> tau(n, 0.0);
    tau[5] = 1.0;
    const double lo5 = before.depths[5], hi5 = before.depths[5] + before.deltas[5] / dir_norm;
    const double far = before.depths[n - 1] + before.deltas[n - 1] / dir_norm;
    ImportanceResample(tau, added, &s, &rng);
    const int total = added > 0 ? n + added : n;
    ASSERT_EQ(static_cast<int>(s.depths.size()), total) << added;
    ASSERT_EQ(static_cast<int>(s.deltas.size()), total) << added;
    EXPECT_TRUE(std::is_sorted(s.depths.begin(), s.depths.end())) << added;
    // Every kept original depth is still there.
    const int keep_every = added > 0 ? 1 : 2;
    for (int i = 0; i < n; i += keep_every) {
      EXPECT_TRUE(std::find(s.depths.begin(), s.depths.end(), before.depths[i]) != s.depths.end())
          << "sample " << i << ", added " << added;
    }
    // The drawn samples lie in interval 5 (the 1e-5 floor of the other
    // intervals makes a draw elsewhere a ~1e-4 event per draw), beside its
    // own stratified sample when every sample is kept.
    int in_interval = 0;
    for (double d : s.depths) in_interval += d >= lo5 && d < hi5;
    EXPECT_EQ(in_interval, added > 0 ? 1 + added : n / 2) << added;
    // The intervals tile [first depth, far] (deltas are along the ray: x dir_norm).
    double length = 0;
    for (int i = 0; i < total; ++i) {
      EXPECT_GT(s.deltas[i], 0) << added;
      length += s.deltas[i] / dir_norm;
    }
    EXPECT_NEAR(length, far - s.depths[0], 1e-12) << added;
  }
}

TEST(ImportanceResample, UniformWeightsSpreadTheDrawnSamples) {
  std::mt19937 rng(5);
  const int n = 64;
  RaySamples s = StratifiedSamples(n, 1.0, 3.0, 1.0, /*jitter=*/false, &rng);
  ImportanceResample(std::vector<double>(n, 0.5), /*added=*/0, &s, &rng);
  // Half the samples on each half of [1, 3] within sampling noise.
  const int low = static_cast<int>(
      std::count_if(s.depths.begin(), s.depths.end(), [](double d) { return d < 2.0; }));
  EXPECT_GE(low, n / 2 - 8);
  EXPECT_LE(low, n / 2 + 8);
  EXPECT_GE(s.depths.front(), 1.0);
  EXPECT_LE(s.depths.back(), 3.0);
}

TEST(ImportanceResample, SingleSampleIsLeftAlone) {
  std::mt19937 rng(7);
  RaySamples s = StratifiedSamples(1, 1.0, 2.0, 1.0, false, &rng);
  const RaySamples before = s;
  ImportanceResample({1.0}, /*added=*/0, &s, &rng);
  EXPECT_EQ(s.depths, before.depths);
  EXPECT_EQ(s.deltas, before.deltas);
  ImportanceResample({1.0}, /*added=*/8, &s, &rng);
  EXPECT_EQ(s.depths, before.depths);
  EXPECT_EQ(s.deltas, before.deltas);
}

TEST(SdfMinimumDepth, VertexOfTheParabolaExactForAQuadratic) {
  std::mt19937 rng(11);
  const RaySamples s = StratifiedSamples(12, 1.0, 5.0, 1.0, /*jitter=*/true, &rng);
  std::vector<double> sdf;
  for (double z : s.depths) sdf.push_back(0.8 * (z - 3.37) * (z - 3.37) - 0.05);
  double z = 0.0;
  ASSERT_TRUE(SdfMinimumDepth(s.depths, sdf, &z));
  // Rounding only: three samples about 1/3 apart, values O(1).
  EXPECT_NEAR(z, 3.37, 1e-12);
  // The smallest sample first or last: no bracket.
  const std::vector<double> rising = s.depths;
  z = -1.0;
  EXPECT_FALSE(SdfMinimumDepth(s.depths, rising, &z));
  EXPECT_EQ(z, -1.0);
  std::vector<double> falling;
  for (double d : s.depths) falling.push_back(-d);
  EXPECT_FALSE(SdfMinimumDepth(s.depths, falling, &z));
  EXPECT_FALSE(SdfMinimumDepth({1.0, 2.0}, {0.5, 0.1}, &z));
  // Equal values (collinear): no vertex.
  EXPECT_FALSE(SdfMinimumDepth({1.0, 2.0, 3.0}, {0.5, 0.5, 0.5}, &z));
}

// A ray that grazes a sphere: the SDF along it, sqrt(d^2 + (z - c)^2) - r,
// is smallest (d - r) at the sphere's centre depth c.
TEST(ImportanceResample, MinSdfSampleLandsWhereTheRayGrazesASphere) {
  const double c = 4.0, r = 0.3, d = 0.95 * r, beta = 0.02;
  const auto sphere = [&](double z) { return std::hypot(d, z - c) - r; };
  for (const int added : {0, 16}) {
    for (int trial = 0; trial < 20; ++trial) {
      std::mt19937 rng(100 + trial);
      RaySamples s = StratifiedSamples(32, 2.0, 6.0, 1.0, /*jitter=*/true, &rng);
      const RaySamples before = s;
      std::vector<double> sdf;
      for (double z : s.depths) sdf.push_back(sphere(z));
      std::vector<double> tau(sdf.size());
      CompositeWeights(static_cast<int>(sdf.size()), sdf.data(), std::log(beta), s.deltas.data(),
                       DensityModel::kNeus, tau.data());
      ImportanceResample(tau, added, &s, &rng, &sdf);
      const int total = added > 0 ? 32 + added : 32;
      ASSERT_EQ(static_cast<int>(s.depths.size()), total);
      EXPECT_TRUE(std::is_sorted(s.depths.begin(), s.depths.end()));
      const int keep_every = added > 0 ? 1 : 2;
      for (int i = 0; i < 32; i += keep_every) {
        EXPECT_TRUE(std::find(s.depths.begin(), s.depths.end(), before.depths[i]) !=
                    s.depths.end());
      }
      // A sample within 2 % of the chord's half-length of the centre, so the
      // sampled minimum is the true one to 1e-4 r (the SDF is quadratic
      // near it with curvature 1 / d).
      double best = 1e9;
      for (double z : s.depths) best = std::min(best, sphere(z));
      EXPECT_NEAR(best, d - r, 1e-4 * r) << "trial " << trial << ", added " << added;
      // So NeuS's opacity is that of the true minimum, > 1/2 inside the
      // silhouette: 1 - Phi(d - r) / Phi(f_0) with f_0 >> beta.
      std::vector<double> after;
      for (double z : s.depths) after.push_back(sphere(z));
      std::vector<double> tau_after(after.size());
      CompositeWeights(total, after.data(), std::log(beta), s.deltas.data(), DensityModel::kNeus,
                       tau_after.data());
      double opacity = 0.0;
      for (double t : tau_after) opacity += t;
      const double expected = 1.0 - 1.0 / (1.0 + std::exp(-(d - r) / beta));
      EXPECT_NEAR(opacity, expected, 2e-3) << "trial " << trial << ", added " << added;
      EXPECT_GT(opacity, 0.5);
    }
  }
}

// Intrinsics of a 100 x 100 camera with focal length 100.
const Eigen::Vector4d kIntrinsics(100, 100, 50, 50);

TEST(ClipDepthsToBox, CentralRayKeepsTheBoxDepthsInsideThePlanes) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1));
  const Pose pose = MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 5));
  double near = 0, far = 0;
  NearFarPlanes(pose, box, 0.2, &near, &far);  // 3.2, 7.2
  double n = near, f = far;
  ASSERT_TRUE(ClipDepthsToBox(pose, box, 0.0, kIntrinsics, Eigen::Vector2d(50, 50), &n, &f));
  EXPECT_NEAR(n, 4, 1e-12);
  EXPECT_NEAR(f, 6, 1e-12);
  // Widened by half the side (1 unit) the box reaches past the near plane,
  // which stays the limit.
  n = near, f = far;
  ASSERT_TRUE(ClipDepthsToBox(pose, box, 0.5, kIntrinsics, Eigen::Vector2d(50, 50), &n, &f));
  EXPECT_NEAR(n, 3.2, 1e-12);
  EXPECT_NEAR(f, 7, 1e-12);
  // An oblique ray through the box's edge region: pixel x = 70 is the
  // direction (0.2, 0, 1), which leaves the slab x <= 1 at depth 5.
  n = near, f = far;
  ASSERT_TRUE(ClipDepthsToBox(pose, box, 0.0, kIntrinsics, Eigen::Vector2d(70, 50), &n, &f));
  EXPECT_NEAR(n, 4, 1e-12);
  EXPECT_NEAR(f, 5, 1e-12);
}

TEST(ClipDepthsToBox, MissingRayKeepsThePlanes) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1));
  const Pose pose = MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 5));
  double near = 3.2, far = 7.2;
  // Direction (0.45, 0, 1): at depth 4..6, x = 1.8..2.7, outside the box.
  EXPECT_FALSE(ClipDepthsToBox(pose, box, 0.0, kIntrinsics, Eigen::Vector2d(95, 50), &near, &far));
  EXPECT_EQ(near, 3.2);
  EXPECT_EQ(far, 7.2);
  // A ray parallel to a slab and outside it: the camera above the box
  // looking along z.
  const Pose above = MakePose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, -3, 5));
  EXPECT_FALSE(ClipDepthsToBox(above, box, 0.0, kIntrinsics, Eigen::Vector2d(50, 50), &near, &far));
  // Widened enough (margin 1: +-3), the same ray meets it.
  EXPECT_TRUE(ClipDepthsToBox(above, box, 1.0, kIntrinsics, Eigen::Vector2d(50, 50), &near, &far));
  EXPECT_NEAR(near, 3.2, 1e-12);
  EXPECT_NEAR(far, 7.2, 1e-12);
}

TEST(ClipDepthsToBox, FollowsTheRootPoseAgainstBruteForce) {
  // Random poses and pixels: every point of the clipped interval lies in the
  // widened box, and points of the planes' range outside it do not (checked
  // on a fine grid of depths; tolerance 1e-9 for the interval's ends).
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1.5, -0.4, -0.7), Eigen::Vector3d(1.2, 0.6, 0.3));
  const double margin = 0.1;
  const Eigen::Vector3d widen = Eigen::Vector3d::Constant(margin * 2.7);
  const Eigen::AlignedBox3d wide(box.min() - widen, box.max() + widen);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  int hits = 0, misses = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Quaterniond q = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    const Pose pose = MakePose(q, Eigen::Vector3d(0.3 * u(rng), 0.3 * u(rng), 4 + u(rng)));
    const Eigen::Vector2d uv(50 + 50 * u(rng), 50 + 50 * u(rng));
    double near = 0, far = 0;
    NearFarPlanes(pose, box, 0.2, &near, &far);
    double n = near, f = far;
    const bool hit = ClipDepthsToBox(pose, box, margin, kIntrinsics, uv, &n, &f);
    hits += hit;
    misses += !hit;
    const Eigen::Vector3d d((uv[0] - 50) / 100, (uv[1] - 50) / 100, 1.0);
    for (int i = 0; i <= 400; ++i) {
      const double z = near + (far - near) * i / 400.0;
      Eigen::Vector3d x_root;
      const Eigen::Vector3d x_cam = z * d;
      PoseInverseTransformPoint(pose.data(), x_cam.data(), x_root.data());
      const bool inside = wide.contains(x_root);
      const bool in_interval = hit && z >= n - 1e-9 && z <= f + 1e-9;
      if (in_interval) {
        EXPECT_TRUE(inside) << "trial " << trial << " z " << z;
      }
      if (!hit || z < n - 1e-6 || z > f + 1e-6) {
        EXPECT_FALSE(inside) << "trial " << trial << " z " << z;
      }
    }
    if (hit) {
      EXPECT_GE(n, near);
      EXPECT_LE(f, far);
    } else {
      EXPECT_EQ(n, near);
      EXPECT_EQ(f, far);
    }
  }
  EXPECT_GT(hits, 20);
  EXPECT_GT(misses, 20);
}

}  // namespace
}  // namespace banmo
