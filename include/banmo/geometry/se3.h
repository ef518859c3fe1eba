// Rigid transforms (SE(3)) templated on the scalar type, for use inside Ceres
// cost functors with Jets.
//
// Storage order of a pose block (kPoseSize = 7 doubles), used everywhere in
// banmo-ceres for root poses, bone transforms and rest-bone orientations:
//   [qw, qx, qy, qz, tx, ty, tz]
// i.e. Ceres' quaternion order followed by the translation. A pose named
// `b_from_a` maps a point expressed in frame a to frame b:
//   x_in_b = R(q) * x_in_a + t.
// Quaternions are normalised on use (QuaternionRotatePoint), so an
// unnormalised block still represents a rotation; in the solver the blocks
// live on ceres::ProductManifold<QuaternionManifold, EuclideanManifold<3>>
// (PoseManifold() below).
#pragma once

#include <ceres/rotation.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace banmo {

inline constexpr int kPoseSize = 7;
inline constexpr int kPoseQw = 0;  // quaternion w, then x, y, z
inline constexpr int kPoseT = 4;   // translation x, y, z

// x_in_b = b_from_a * x_in_a.
template <typename T>
inline void PoseTransformPoint(const T* b_from_a, const T* x_in_a, T* x_in_b) {
  ceres::QuaternionRotatePoint(b_from_a + kPoseQw, x_in_a, x_in_b);
  x_in_b[0] += b_from_a[kPoseT + 0];
  x_in_b[1] += b_from_a[kPoseT + 1];
  x_in_b[2] += b_from_a[kPoseT + 2];
}

// Rotation only (directions): d_in_b = R(b_from_a) * d_in_a.
template <typename T>
inline void PoseRotateVector(const T* b_from_a, const T* d_in_a, T* d_in_b) {
  ceres::QuaternionRotatePoint(b_from_a + kPoseQw, d_in_a, d_in_b);
}

// x_in_a = b_from_a^{-1} * x_in_b = R^T (x_in_b - t).
template <typename T>
inline void PoseInverseTransformPoint(const T* b_from_a, const T* x_in_b, T* x_in_a) {
  const T conj[4] = {b_from_a[0], -b_from_a[1], -b_from_a[2], -b_from_a[3]};
  const T d[3] = {x_in_b[0] - b_from_a[kPoseT + 0], x_in_b[1] - b_from_a[kPoseT + 1],
                  x_in_b[2] - b_from_a[kPoseT + 2]};
  ceres::QuaternionRotatePoint(conj, d, x_in_a);
}

// Inverse rotation only: d_in_a = R(b_from_a)^T d_in_b.
template <typename T>
inline void PoseInverseRotateVector(const T* b_from_a, const T* d_in_b, T* d_in_a) {
  const T conj[4] = {b_from_a[0], -b_from_a[1], -b_from_a[2], -b_from_a[3]};
  ceres::QuaternionRotatePoint(conj, d_in_b, d_in_a);
}

// c_from_a = c_from_b * b_from_a. The result's quaternion has the product of
// the input norms (it is not renormalised, so derivatives stay smooth).
template <typename T>
inline void PoseCompose(const T* c_from_b, const T* b_from_a, T* c_from_a) {
  ceres::QuaternionProduct(c_from_b + kPoseQw, b_from_a + kPoseQw, c_from_a + kPoseQw);
  PoseTransformPoint(c_from_b, b_from_a + kPoseT, c_from_a + kPoseT);
}

// a_from_b = (b_from_a)^{-1}.
template <typename T>
inline void PoseInverse(const T* b_from_a, T* a_from_b) {
  a_from_b[0] = b_from_a[0];
  a_from_b[1] = -b_from_a[1];
  a_from_b[2] = -b_from_a[2];
  a_from_b[3] = -b_from_a[3];
  const T minus_t[3] = {-b_from_a[kPoseT + 0], -b_from_a[kPoseT + 1], -b_from_a[kPoseT + 2]};
  ceres::QuaternionRotatePoint(a_from_b + kPoseQw, minus_t, a_from_b + kPoseT);
}

// Identity pose.
template <typename T>
inline void PoseSetIdentity(T* pose) {
  pose[0] = T(1);
  for (int i = 1; i < kPoseSize; ++i) pose[i] = T(0);
}

// Conversions for non-templated code (double only).
using Pose = Eigen::Matrix<double, kPoseSize, 1>;

Pose PoseIdentity();
Pose PoseFromIsometry(const Eigen::Isometry3d& b_from_a);
Eigen::Isometry3d IsometryFromPose(const double* b_from_a);
// Pose from an angle-axis vector (radians) and a translation.
Pose PoseFromAngleAxis(const Eigen::Vector3d& angle_axis, const Eigen::Vector3d& translation);
// b_from_a * T(origin): the pose of frame a moved so that its origin is the
// point `origin` of a (same rotation, translation t + R origin; the rotation
// is copied, not round-tripped through a matrix).
Pose PoseWithOriginAt(const Pose& b_from_a, const Eigen::Vector3d& origin);
// Geodesic rotation angle between two poses' rotations, in radians.
double RotationAngleBetween(const double* pose_a, const double* pose_b);
// The pose a fraction w of the way from a to b (w in [0, 1]): the rotation
// by spherical linear interpolation on the shorter arc, the translation
// linearly (w = 0 gives a, w = 1 gives b, to rounding).
Pose PoseInterpolate(const Pose& a, const Pose& b, double w);

}  // namespace banmo
