// The rotation nearest to a 3 x 3 matrix (Frobenius norm): with m = U S V^T,
// U diag(1, 1, det(U V^T)) V^T. Used to average rotations (the projection of
// their sum) and to align rotation tracks; eval/icp.cc's Umeyama step keeps
// its own SVD because it also needs the singular values for the scale.
#pragma once

#include <Eigen/Core>
#include <Eigen/SVD>

namespace banmo {

inline Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0) u.col(2) *= -1;
  return u * svd.matrixV().transpose();
}

}  // namespace banmo
