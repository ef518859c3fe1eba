// Ceres manifolds for banmo's pose-like parameter blocks.
#pragma once

#include <ceres/manifold.h>

#include <cmath>
#include <memory>

namespace banmo {

// The step quaternion of ceres::QuaternionManifold::Plus for a tangent step
// w: [cos|w|, sin|w| w / |w|]. Below 1e-20 squared (the value 0 of a Jet at
// the expansion point) its first-order form [1, w], so derivatives at
// w = 0 are exact. Any scalar (Jets for autodiff manifolds).
template <typename T>
void StepQuaternion(const T* w, T* q) {
  const T squared = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  if (squared < T(1e-20)) {
    q[0] = T(1);
    for (int k = 0; k < 3; ++k) q[k + 1] = w[k];
    return;
  }
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T norm = sqrt(squared);
  const T s = sin(norm) / norm;
  q[0] = cos(norm);
  for (int k = 0; k < 3; ++k) q[k + 1] = s * w[k];
}

// One pose [qw, qx, qy, qz, tx, ty, tz] (geometry/se3.h):
// ProductManifold<QuaternionManifold, EuclideanManifold<3>>; ambient 7,
// tangent 6. The caller owns the result (or hands it to a ceres::Problem).
std::unique_ptr<ceres::Manifold> MakePoseManifold();

// `count` poses stored one after another (e.g. the B bone transforms of a
// frame): ambient 7 count, tangent 6 count, each pose as MakePoseManifold.
std::unique_ptr<ceres::Manifold> MakeStackedPoseManifold(int count);

// `count` poses stored one after another, pose i turning about its own
// pivot point: pivots[pivot_stride * i + pivot_offset + 0..2], read at each
// call (the pivots may be another parameter block, e.g. the rest bone
// centres, which move during a solve). Ambient 7 count, tangent 6 count.
// The rotation part of a step is that of ceres::QuaternionManifold
// (q' = [cos|w|, sin|w| w / |w|] * q); the translation part moves the posed
// pivot R c + t by v and nothing else:
//   t' = t + v + R c - R' c,
// so turning a pose about its pivot is one tangent coordinate, as it is
// about the origin for MakeStackedPoseManifold. For the bone transforms J_b^t
// (deform/bones.h), which act about the canonical origin: a limb turns about
// its own bone instead of swinging round the origin with a translation that
// has to follow. Jacobians by ceres::AutoDiffManifold.
std::unique_ptr<ceres::Manifold> MakeStackedPivotPoseManifold(int count, const double* pivots,
                                                              int pivot_stride, int pivot_offset);

// `count` blocks of `stride` doubles, each with a unit quaternion (Ceres
// order w, x, y, z) at `quaternion_offset` and Euclidean values elsewhere
// (e.g. the rest bones [centre 3, quaternion 4, log-scales 3]): tangent size
// (stride - 1) count.
std::unique_ptr<ceres::Manifold> MakeStackedQuaternionBlockManifold(int count, int stride,
                                                                    int quaternion_offset);

}  // namespace banmo
