#include "banmo/geometry/pose_manifold.h"

#include <ceres/product_manifold.h>

#include <Eigen/Core>

#include "banmo/util/logging.h"

namespace banmo {
namespace {

// `count` blocks of `stride` doubles with a quaternion at `q_offset`: the
// quaternion part moves on ceres::QuaternionManifold, the rest is Euclidean.
class StackedQuaternionBlockManifold final : public ceres::Manifold {
 public:
  StackedQuaternionBlockManifold(int count, int stride, int q_offset)
      : count_(count), stride_(stride), q_offset_(q_offset) {
    CHECK_GT(count, 0);
    CHECK_GE(q_offset, 0);
    CHECK_LE(q_offset + 4, stride);
  }
  int AmbientSize() const override { return count_ * stride_; }
  int TangentSize() const override { return count_ * (stride_ - 1); }

  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    for (int i = 0; i < count_; ++i) {
      const double* xi = x + stride_ * i;
      const double* di = delta + (stride_ - 1) * i;
      double* yi = x_plus_delta + stride_ * i;
      for (int k = 0; k < q_offset_; ++k) yi[k] = xi[k] + di[k];
      if (!quaternion_.Plus(xi + q_offset_, di + q_offset_, yi + q_offset_)) return false;
      for (int k = q_offset_ + 4; k < stride_; ++k) yi[k] = xi[k] + di[k - 1];
    }
    return true;
  }

  bool PlusJacobian(const double* x, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
        jacobian, AmbientSize(), TangentSize());
    jac.setZero();
    for (int i = 0; i < count_; ++i) {
      const int r0 = stride_ * i, c0 = (stride_ - 1) * i;
      for (int k = 0; k < q_offset_; ++k) jac(r0 + k, c0 + k) = 1.0;
      double q_jac[4 * 3];
      if (!quaternion_.PlusJacobian(x + r0 + q_offset_, q_jac)) return false;
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 3; ++c) jac(r0 + q_offset_ + r, c0 + q_offset_ + c) = q_jac[3 * r + c];
      }
      for (int k = q_offset_ + 4; k < stride_; ++k) jac(r0 + k, c0 + k - 1) = 1.0;
    }
    return true;
  }

  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    for (int i = 0; i < count_; ++i) {
      const double* yi = y + stride_ * i;
      const double* xi = x + stride_ * i;
      double* di = y_minus_x + (stride_ - 1) * i;
      for (int k = 0; k < q_offset_; ++k) di[k] = yi[k] - xi[k];
      if (!quaternion_.Minus(yi + q_offset_, xi + q_offset_, di + q_offset_)) return false;
      for (int k = q_offset_ + 4; k < stride_; ++k) di[k - 1] = yi[k] - xi[k];
    }
    return true;
  }

  bool MinusJacobian(const double* x, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
        jacobian, TangentSize(), AmbientSize());
    jac.setZero();
    for (int i = 0; i < count_; ++i) {
      const int c0 = stride_ * i, r0 = (stride_ - 1) * i;
      for (int k = 0; k < q_offset_; ++k) jac(r0 + k, c0 + k) = 1.0;
      double q_jac[3 * 4];
      if (!quaternion_.MinusJacobian(x + c0 + q_offset_, q_jac)) return false;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) jac(r0 + q_offset_ + r, c0 + q_offset_ + c) = q_jac[4 * r + c];
      }
      for (int k = q_offset_ + 4; k < stride_; ++k) jac(r0 + k - 1, c0 + k) = 1.0;
    }
    return true;
  }

 private:
  const int count_, stride_, q_offset_;
  const ceres::QuaternionManifold quaternion_;
};

}  // namespace

std::unique_ptr<ceres::Manifold> MakePoseManifold() {
  using PoseManifold =
      ceres::ProductManifold<ceres::QuaternionManifold, ceres::EuclideanManifold<3>>;
  return std::make_unique<PoseManifold>(ceres::QuaternionManifold(), ceres::EuclideanManifold<3>());
}

std::unique_ptr<ceres::Manifold> MakeStackedPoseManifold(int count) {
  return std::make_unique<StackedQuaternionBlockManifold>(count, 7, 0);
}

std::unique_ptr<ceres::Manifold> MakeStackedQuaternionBlockManifold(int count, int stride,
                                                                    int quaternion_offset) {
  return std::make_unique<StackedQuaternionBlockManifold>(count, stride, quaternion_offset);
}

}  // namespace banmo
