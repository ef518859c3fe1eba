#include "banmo/geometry/se3.h"

#include <algorithm>
#include <cmath>

namespace banmo {

Pose PoseWithOriginAt(const Pose& b_from_a, const Eigen::Vector3d& origin) {
  Pose out = b_from_a;
  const Eigen::Vector3d t = IsometryFromPose(b_from_a.data()).linear() * origin;
  for (int k = 0; k < 3; ++k) out[kPoseT + k] += t[k];
  return out;
}

Pose PoseIdentity() {
  Pose p;
  PoseSetIdentity(p.data());
  return p;
}

Pose PoseFromIsometry(const Eigen::Isometry3d& b_from_a) {
  const Eigen::Quaterniond q(b_from_a.rotation());
  Pose p;
  p << q.w(), q.x(), q.y(), q.z(), b_from_a.translation();
  return p;
}

Eigen::Isometry3d IsometryFromPose(const double* b_from_a) {
  Eigen::Quaterniond q(b_from_a[0], b_from_a[1], b_from_a[2], b_from_a[3]);
  q.normalize();
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = q.toRotationMatrix();
  out.translation() = Eigen::Vector3d(b_from_a[4], b_from_a[5], b_from_a[6]);
  return out;
}

Pose PoseFromAngleAxis(const Eigen::Vector3d& angle_axis, const Eigen::Vector3d& translation) {
  Pose p;
  ceres::AngleAxisToQuaternion(angle_axis.data(), p.data());
  p.tail<3>() = translation;
  return p;
}

double RotationAngleBetween(const double* pose_a, const double* pose_b) {
  Eigen::Quaterniond qa(pose_a[0], pose_a[1], pose_a[2], pose_a[3]);
  Eigen::Quaterniond qb(pose_b[0], pose_b[1], pose_b[2], pose_b[3]);
  qa.normalize();
  qb.normalize();
  return qa.angularDistance(qb);
}

Pose PoseInterpolate(const Pose& a, const Pose& b, double w) {
  const Eigen::Quaterniond qa = Eigen::Quaterniond(a[0], a[1], a[2], a[3]).normalized();
  const Eigen::Quaterniond qb = Eigen::Quaterniond(b[0], b[1], b[2], b[3]).normalized();
  // Eigen's slerp takes the shorter arc (it flips qb when qa . qb < 0).
  const Eigen::Quaterniond q = qa.slerp(w, qb);
  Pose out;
  out << q.w(), q.x(), q.y(), q.z(), (1.0 - w) * a.tail<3>() + w * b.tail<3>();
  return out;
}

}  // namespace banmo
