#include "banmo/geometry/pose_manifold.h"

#include <ceres/autodiff_manifold.h>
#include <ceres/product_manifold.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <vector>

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

// One pose [qw, qx, qy, qz, tx, ty, tz] turning about the pivot c
// (MakeStackedPivotPoseManifold), for ceres::AutoDiffManifold<., 7, 6>.
class PivotPoseFunctor {
 public:
  explicit PivotPoseFunctor(const double* pivot) : pivot_(pivot) {}

  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    // As ceres::QuaternionManifold::Plus (StepQuaternion: exact
    // derivatives at delta = 0).
    T dq[4];
    StepQuaternion(delta, dq);
    ceres::QuaternionProduct(dq, x, x_plus_delta);
    T rc[3], rc_new[3];
    const T c[3] = {T(pivot_[0]), T(pivot_[1]), T(pivot_[2])};
    ceres::QuaternionRotatePoint(x, c, rc);
    ceres::QuaternionRotatePoint(x_plus_delta, c, rc_new);
    for (int k = 0; k < 3; ++k) x_plus_delta[4 + k] = x[4 + k] + delta[3 + k] + rc[k] - rc_new[k];
    return true;
  }

  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    // As ceres::QuaternionManifold::Minus: the rotation vector of
    // y * conj(x), halved (first-order form near the identity).
    const T conj_x[4] = {x[0], -x[1], -x[2], -x[3]};
    T z[4];
    ceres::QuaternionProduct(y, conj_x, z);
    const T squared = z[1] * z[1] + z[2] * z[2] + z[3] * z[3];
    if (squared < T(1e-20)) {
      for (int k = 0; k < 3; ++k) y_minus_x[k] = z[k + 1];
    } else {
      using std::atan2;
      using std::sqrt;
      const T norm = sqrt(squared);
      const T s = atan2(norm, z[0]) / norm;
      for (int k = 0; k < 3; ++k) y_minus_x[k] = s * z[k + 1];
    }
    T rx[3], ry[3];
    const T c[3] = {T(pivot_[0]), T(pivot_[1]), T(pivot_[2])};
    ceres::QuaternionRotatePoint(x, c, rx);
    ceres::QuaternionRotatePoint(y, c, ry);
    for (int k = 0; k < 3; ++k) y_minus_x[3 + k] = y[4 + k] - x[4 + k] + ry[k] - rx[k];
    return true;
  }

 private:
  const double* pivot_;
};

// `count` manifolds of equal sizes side by side (block-diagonal Jacobians).
class StackedManifold final : public ceres::Manifold {
 public:
  explicit StackedManifold(std::vector<std::unique_ptr<ceres::Manifold>> parts)
      : parts_(std::move(parts)) {
    CHECK(!parts_.empty());
    ambient_ = parts_[0]->AmbientSize();
    tangent_ = parts_[0]->TangentSize();
    for (const auto& p : parts_) {
      CHECK_EQ(p->AmbientSize(), ambient_);
      CHECK_EQ(p->TangentSize(), tangent_);
    }
  }
  int AmbientSize() const override { return ambient_ * Count(); }
  int TangentSize() const override { return tangent_ * Count(); }

  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    for (int i = 0; i < Count(); ++i) {
      if (!parts_[i]->Plus(x + ambient_ * i, delta + tangent_ * i, x_plus_delta + ambient_ * i)) {
        return false;
      }
    }
    return true;
  }
  bool PlusJacobian(const double* x, double* jacobian) const override {
    return Blocks(x, AmbientSize(), TangentSize(), ambient_, tangent_, jacobian,
                  [](const ceres::Manifold& m, const double* xi, double* j) {
                    return m.PlusJacobian(xi, j);
                  });
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    for (int i = 0; i < Count(); ++i) {
      if (!parts_[i]->Minus(y + ambient_ * i, x + ambient_ * i, y_minus_x + tangent_ * i)) {
        return false;
      }
    }
    return true;
  }
  bool MinusJacobian(const double* x, double* jacobian) const override {
    return Blocks(x, TangentSize(), AmbientSize(), tangent_, ambient_, jacobian,
                  [](const ceres::Manifold& m, const double* xi, double* j) {
                    return m.MinusJacobian(xi, j);
                  });
  }

 private:
  int Count() const { return static_cast<int>(parts_.size()); }
  // Block-diagonal rows x cols (row-major) from each part's r x c block.
  template <class F>
  bool Blocks(const double* x, int rows, int cols, int r, int c, double* jacobian, F part) const {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jac(
        jacobian, rows, cols);
    jac.setZero();
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> block(r, c);
    for (int i = 0; i < Count(); ++i) {
      if (!part(*parts_[i], x + ambient_ * i, block.data())) return false;
      jac.block(r * i, c * i, r, c) = block;
    }
    return true;
  }

  std::vector<std::unique_ptr<ceres::Manifold>> parts_;
  int ambient_ = 0, tangent_ = 0;
};

}  // namespace

std::unique_ptr<ceres::Manifold> MakeStackedPivotPoseManifold(int count, const double* pivots,
                                                              int pivot_stride, int pivot_offset) {
  CHECK_GT(count, 0);
  CHECK(pivots != nullptr);
  std::vector<std::unique_ptr<ceres::Manifold>> parts;
  for (int i = 0; i < count; ++i) {
    parts.push_back(std::make_unique<ceres::AutoDiffManifold<PivotPoseFunctor, 7, 6>>(
        new PivotPoseFunctor(pivots + pivot_stride * i + pivot_offset)));
  }
  return std::make_unique<StackedManifold>(std::move(parts));
}

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
