// Axis-aligned boxes: the canonical bounds that the solver samples in, the
// model file stores and extraction and `banmo render` use.
#pragma once

#include <Eigen/Geometry>

namespace banmo {

// A box to sample or extract in: finite corners and max > min on every axis
// (an empty, flat, infinite or NaN box is not).
inline bool IsValidBox(const Eigen::AlignedBox3d& box) {
  return box.min().allFinite() && box.max().allFinite() &&
         ((box.max() - box.min()).array() > 0.0).all();
}

}  // namespace banmo
