#include "banmo/geometry/pose_manifold.h"

#include <ceres/product_manifold.h>

namespace banmo {

std::unique_ptr<ceres::Manifold> MakePoseManifold() {
  using PoseManifold = ceres::ProductManifold<ceres::QuaternionManifold, ceres::EuclideanManifold<3>>;
  return std::make_unique<PoseManifold>(ceres::QuaternionManifold(), ceres::EuclideanManifold<3>());
}

}  // namespace banmo
