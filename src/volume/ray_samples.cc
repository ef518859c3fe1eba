#include "banmo/volume/ray_samples.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "banmo/geometry/camera.h"
#include "banmo/util/logging.h"

namespace banmo {

void NearFarPlanes(const Pose& camera_from_root, const Eigen::AlignedBox3d& canonical_bounds,
                   double margin, double* near, double* far) {
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner =
        canonical_bounds.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c));
    Eigen::Vector3d x;
    PoseTransformPoint(camera_from_root.data(), corner.data(), x.data());
    zmin = std::min(zmin, x.z());
    zmax = std::max(zmax, x.z());
  }
  // Keep the near plane in front of the camera even for boxes around it.
  *near = std::max(zmin * (1.0 - margin), 1e-3);
  *far = std::max(zmax * (1.0 + margin), *near + 1e-3);
}

bool ClipDepthsToBox(const Pose& camera_from_root, const Eigen::AlignedBox3d& canonical_bounds,
                     double margin, const Eigen::Vector4d& intrinsics, const Eigen::Vector2d& uv,
                     double* near, double* far) {
  CHECK(!canonical_bounds.isEmpty());
  CHECK_GE(margin, 0.0);
  const Eigen::Vector3d widen =
      Eigen::Vector3d::Constant(margin * canonical_bounds.sizes().maxCoeff());
  const Eigen::Vector3d lo = canonical_bounds.min() - widen, hi = canonical_bounds.max() + widen;
  // The ray in root coordinates: o + z e, z the camera depth.
  Eigen::Vector3d d;
  PixelToRayDirection(intrinsics.data(), uv.data(), d.data());
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  Eigen::Vector3d o, e;
  PoseInverseTransformPoint(camera_from_root.data(), zero.data(), o.data());
  PoseInverseRotateVector(camera_from_root.data(), d.data(), e.data());
  double z0 = *near, z1 = *far;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(e[a]) < 1e-12) {  // parallel to the slab: inside it or never
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    double ta = (lo[a] - o[a]) / e[a], tb = (hi[a] - o[a]) / e[a];
    if (ta > tb) std::swap(ta, tb);
    z0 = std::max(z0, ta);
    z1 = std::min(z1, tb);
  }
  // A sliver shorter than a millionth of the planes' range is a miss too.
  if (!(z1 - z0 > 1e-6 * (*far - *near))) return false;
  *near = z0;
  *far = z1;
  return true;
}

bool SdfMinimumDepth(const std::vector<double>& depths, const std::vector<double>& sdf,
                     double* depth) {
  const int n = static_cast<int>(depths.size());
  CHECK_EQ(static_cast<int>(sdf.size()), n);
  if (n < 3) return false;
  const int k = static_cast<int>(std::min_element(sdf.begin(), sdf.end()) - sdf.begin());
  if (k == 0 || k == n - 1) return false;
  // Vertex of the parabola through (z_j, f_j), j = k - 1, k, k + 1 (any
  // spacing). f_k is the smallest, so the parabola opens upwards (or is a
  // line through three equal values: den == 0) and its vertex lies in
  // [z_{k-1}, z_{k+1}]; the clamp only guards rounding.
  const double z0 = depths[k - 1], z1 = depths[k], z2 = depths[k + 1];
  const double f0 = sdf[k - 1], f1 = sdf[k], f2 = sdf[k + 1];
  const double a = (z1 - z0) * (f1 - f2), b = (z1 - z2) * (f1 - f0);
  const double den = a - b;
  if (!(std::abs(den) > 0.0)) return false;
  *depth = std::clamp(z1 - 0.5 * ((z1 - z0) * a - (z1 - z2) * b) / den, z0, z2);
  return true;
}

void ImportanceResample(const std::vector<double>& tau, int added, RaySamples* samples,
                        std::mt19937* rng, const std::vector<double>* sdf) {
  const int n = static_cast<int>(samples->depths.size());
  CHECK_EQ(static_cast<int>(tau.size()), n);
  CHECK_GE(added, 0);
  if (n < 2) return;
  // Interval i spans [depth_i, depth_i + delta_i / dir_norm).
  const double dir_norm = samples->dir_norm;
  std::vector<double> lo(n), hi(n), cdf(n + 1, 0.0);
  for (int i = 0; i < n; ++i) {
    lo[i] = samples->depths[i];
    hi[i] = samples->depths[i] + samples->deltas[i] / dir_norm;
    cdf[i + 1] = cdf[i] + std::max(tau[i], 0.0) + 1e-5;  // floor keeps empty rays sampled
  }
  // added == 0: the even samples kept, the odd ones redrawn (n in all);
  // added > 0: every sample kept and `added` drawn (n + added).
  const int total = added > 0 ? n + added : n;
  const int keep_every = added > 0 ? 1 : 2;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> depths;
  depths.reserve(total);
  for (int i = 0; i < n; i += keep_every) depths.push_back(samples->depths[i]);
  const int kept = static_cast<int>(depths.size());
  while (static_cast<int>(depths.size()) < total) {
    const double u = unit(*rng) * cdf[n];
    const int i =
        std::min<int>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin() - 1, n - 1);
    const double f = (u - cdf[i]) / std::max(cdf[i + 1] - cdf[i], 1e-300);
    depths.push_back(lo[i] + f * (hi[i] - lo[i]));
  }
  if (sdf != nullptr && total > kept) {
    // The last drawn sample goes to the SDF minimum (header).
    double z = 0.0;
    if (SdfMinimumDepth(samples->depths, *sdf, &z)) depths.back() = z;
  }
  std::sort(depths.begin(), depths.end());
  const double far = hi[n - 1];
  samples->depths = depths;
  samples->deltas.resize(total);
  for (int i = 0; i < total; ++i) {
    const double next = i + 1 < total ? depths[i + 1] : far;
    samples->deltas[i] = std::max(next - depths[i], 1e-9) * dir_norm;
  }
}

}  // namespace banmo
