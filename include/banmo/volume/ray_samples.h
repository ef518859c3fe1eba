// Where the depth samples of a pixel ray go (BANMo, Yang et al. CVPR 2022,
// Sec. 3.1): the near and far planes of a frame, the length of a ray's
// direction, and the importance resampling of importance_depth sampling.
// Shared by the solver's ray sampler (optim/ray_sampler.h) and the pictures
// of `banmo render` (visualize/render.h), so both place samples alike.
// Stratified samples themselves: volume/volume_rendering.h.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <random>
#include <vector>

#include "banmo/geometry/se3.h"
#include "banmo/volume/volume_rendering.h"

namespace banmo {

// Near and far camera depths of a frame: the 8 corners of the canonical
// bounds pushed through the root pose G^t, widened by `margin` (0.2 = +-20 %).
void NearFarPlanes(const Pose& camera_from_root, const Eigen::AlignedBox3d& canonical_bounds,
                   double margin, double* near, double* far);

// Clips a ray's depth interval [*near, *far] (camera z, from NearFarPlanes)
// to the part of the ray inside the canonical box `canonical_bounds` widened
// by `margin` times its largest side on every side (the widening leaves room
// for articulated parts that leave the canonical box). The ray is the one
// through pixel position uv of a camera with intrinsics [fx, fy, cx, cy]
// under camera_from_root (canonical coordinates are root coordinates).
// Returns false, and leaves the interval as it is, when the ray misses the
// widened box or meets it only outside [*near, *far]: such a ray sees no
// object and keeps its plane-to-plane samples.
bool ClipDepthsToBox(const Pose& camera_from_root, const Eigen::AlignedBox3d& canonical_bounds,
                     double margin, const Eigen::Vector4d& intrinsics, const Eigen::Vector2d& uv,
                     double* near, double* far);

// Length of the direction (z = 1, geometry/camera.h) of the ray through pixel
// position uv: |((u - cx) / fx, (v - cy) / fy, 1)|; RaySamples::dir_norm.
// intrinsics = [fx, fy, cx, cy].
inline double RayDirectionLength(const Eigen::Vector4d& intrinsics, const Eigen::Vector2d& uv) {
  return Eigen::Vector3d((uv[0] - intrinsics[2]) / intrinsics[0],
                         (uv[1] - intrinsics[3]) / intrinsics[1], 1.0)
      .norm();
}

// Importance resampling (NeRF's hierarchical sampling, one level): depths
// drawn from the piecewise-constant density given by the rendering weights
// `tau` over the samples' intervals. added == 0 replaces half of `samples`
// (the odd-indexed ones), so a ray keeps its n samples; added > 0 keeps all
// n and adds `added` drawn ones (n + added). The depths stay sorted and the
// interval lengths are recomputed. Used by importance_depth sampling
// (SamplingConfig::importance_samples is `added`).
//
// With `sdf` (the first pass's SDF at `samples`, SamplingConfig::
// min_sdf_sample), the last drawn depth is replaced by SdfMinimumDepth's
// (when it finds one):
// under NeuS's density a ray's opacity is 1 - Phi(f_min) / Phi(f_0)
// (volume_rendering.h), so a ray that grazes a thin part or passes just
// outside one renders its opacity only if a sample lands near the SDF
// minimum, which stratified and weight-drawn samples hit only by chance
// (on the default scene the 0.5-opacity silhouette of `banmo render` was
// up to 1 px thinner along the legs than the zero level set's).
void ImportanceResample(const std::vector<double>& tau, int added, RaySamples* samples,
                        std::mt19937* rng, const std::vector<double>* sdf = nullptr);

// Depth of a ray's SDF minimum estimated from its samples (sorted depths):
// the vertex of the parabola through the smallest SDF sample and its two
// neighbours (any spacing), clamped to their interval. Exact for an SDF
// quadratic in depth near its minimum (to second order, a ray past a sphere
// or a cylinder). False, *depth untouched, when the smallest sample is the
// first or the last (no bracket) or the three are collinear.
bool SdfMinimumDepth(const std::vector<double>& depths, const std::vector<double>& sdf,
                     double* depth);

}  // namespace banmo
