// Ceres manifold for a pose block in banmo's storage order
// [qw, qx, qy, qz, tx, ty, tz] (see geometry/se3.h).
#pragma once

#include <ceres/manifold.h>

#include <memory>

namespace banmo {

// ceres::ProductManifold<QuaternionManifold, EuclideanManifold<3>>: ambient
// size 7, tangent size 6. The caller owns the returned object (or hands it to
// a ceres::Problem, which takes ownership by default).
std::unique_ptr<ceres::Manifold> MakePoseManifold();

}  // namespace banmo
