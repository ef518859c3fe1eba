// Ceres manifolds for banmo's pose-like parameter blocks.
#pragma once

#include <ceres/manifold.h>

#include <memory>

namespace banmo {

// One pose [qw, qx, qy, qz, tx, ty, tz] (geometry/se3.h):
// ProductManifold<QuaternionManifold, EuclideanManifold<3>>; ambient 7,
// tangent 6. The caller owns the result (or hands it to a ceres::Problem).
std::unique_ptr<ceres::Manifold> MakePoseManifold();

// `count` poses stored one after another (e.g. the B bone transforms of a
// frame): ambient 7 count, tangent 6 count, each pose as MakePoseManifold.
std::unique_ptr<ceres::Manifold> MakeStackedPoseManifold(int count);

// `count` blocks of `stride` doubles, each with a unit quaternion (Ceres
// order w, x, y, z) at `quaternion_offset` and Euclidean values elsewhere
// (e.g. the rest bones [centre 3, quaternion 4, log-scales 3]): tangent size
// (stride - 1) count.
std::unique_ptr<ceres::Manifold> MakeStackedQuaternionBlockManifold(int count, int stride,
                                                                    int quaternion_offset);

}  // namespace banmo
