// Pinhole camera, templated for Jets.
//
// Intrinsics block (kIntrinsicsSize = 4): [fx, fy, cx, cy], in pixels.
// Pixel convention: the centre of the pixel in column i, row j is at
// (u, v) = (i + 0.5, j + 0.5); u grows to the right, v downwards, and the
// camera looks along +z (OpenCV convention).
#pragma once

#include <Eigen/Core>

namespace banmo {

inline constexpr int kIntrinsicsSize = 4;

// Points closer than this (in the camera's z, scene units) are projected as if
// they were at this depth: samples behind the camera give finite, zero-slope
// (in z) projections rather than Inf/NaN.
inline constexpr double kMinProjectionDepth = 1e-4;

// uv = projection of point x_in_cam.
template <typename T>
inline void ProjectPoint(const T* intrinsics, const T* x_in_cam, T* uv) {
  T z = x_in_cam[2];
  if (z < T(kMinProjectionDepth)) z = T(kMinProjectionDepth);
  uv[0] = intrinsics[0] * x_in_cam[0] / z + intrinsics[2];
  uv[1] = intrinsics[1] * x_in_cam[1] / z + intrinsics[3];
}

// Direction (not normalised, z = 1) of the ray through pixel position uv.
template <typename T>
inline void PixelToRayDirection(const T* intrinsics, const T* uv, T* dir_in_cam) {
  dir_in_cam[0] = (uv[0] - intrinsics[2]) / intrinsics[0];
  dir_in_cam[1] = (uv[1] - intrinsics[3]) / intrinsics[1];
  dir_in_cam[2] = T(1);
}

struct PinholeCamera {
  int width = 0;
  int height = 0;
  Eigen::Vector4d intrinsics = Eigen::Vector4d(1, 1, 0, 0);  // fx, fy, cx, cy

  // True when sizes and focal lengths are positive and finite.
  bool IsValid() const;
};

}  // namespace banmo
