#include "banmo/volume/ray_samples.h"

#include <algorithm>
#include <cmath>
#include <limits>

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

void ImportanceResample(const std::vector<double>& tau, RaySamples* samples, std::mt19937* rng) {
  const int n = static_cast<int>(samples->depths.size());
  CHECK_EQ(static_cast<int>(tau.size()), n);
  if (n < 2) return;
  // Interval i spans [depth_i, depth_i + delta_i / dir_norm).
  const double dir_norm = samples->dir_norm;
  std::vector<double> lo(n), hi(n), cdf(n + 1, 0.0);
  for (int i = 0; i < n; ++i) {
    lo[i] = samples->depths[i];
    hi[i] = samples->depths[i] + samples->deltas[i] / dir_norm;
    cdf[i + 1] = cdf[i] + std::max(tau[i], 0.0) + 1e-5;  // floor keeps empty rays sampled
  }
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> depths;
  depths.reserve(n);
  for (int i = 0; i < n; i += 2) depths.push_back(samples->depths[i]);
  while (static_cast<int>(depths.size()) < n) {
    const double u = unit(*rng) * cdf[n];
    const int i =
        std::min<int>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin() - 1, n - 1);
    const double f = (u - cdf[i]) / std::max(cdf[i + 1] - cdf[i], 1e-300);
    depths.push_back(lo[i] + f * (hi[i] - lo[i]));
  }
  std::sort(depths.begin(), depths.end());
  const double far = hi[n - 1];
  samples->depths = depths;
  for (int i = 0; i < n; ++i) {
    const double next = i + 1 < n ? depths[i + 1] : far;
    samples->deltas[i] = std::max(next - depths[i], 1e-9) * dir_norm;
  }
}

}  // namespace banmo
