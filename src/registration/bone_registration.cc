#include "banmo/registration/bone_registration.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/cubic_interpolation.h>
#include <ceres/dynamic_autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>
#include <ceres/solver.h>
#include <glog/logging.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <random>

#include "banmo/deform/bones.h"
#include "banmo/extract/extract.h"
#include "banmo/geometry/camera.h"
#include "banmo/geometry/nearest_neighbors.h"
#include "banmo/geometry/pose_manifold.h"
#include "banmo/util/error.h"
#include "banmo/util/median.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace {

// The pixel of a skinned point: Project(K, G sum_k w_k J_{b_k} x), the
// bone transforms J_{b_k} in `parameters` (in the order of point.bones).
template <typename T>
void ProjectSkinnedPoint(const SkinnedPoint& point, const Pose& camera_from_root,
                         const Eigen::Vector4d& intrinsics, T const* const* parameters, T* uv) {
  const T x[3] = {T(point.x[0]), T(point.x[1]), T(point.x[2])};
  T blended[3] = {T(0), T(0), T(0)};
  for (size_t k = 0; k < point.bones.size(); ++k) {
    T z[3];
    PoseTransformPoint(parameters[k], x, z);
    for (int i = 0; i < 3; ++i) blended[i] += T(point.weights[k]) * z[i];
  }
  T g[kPoseSize], K[4], cam[3];
  for (int i = 0; i < kPoseSize; ++i) g[i] = T(camera_from_root[i]);
  for (int i = 0; i < 4; ++i) K[i] = T(intrinsics[i]);
  PoseTransformPoint(g, blended, cam);
  ProjectPoint(K, cam, uv);
}

struct SkinnedPixelResidual {
  SkinnedPixelResidual(const SkinnedPoint& p, const Pose& g, const Eigen::Vector4d& k,
                       const Eigen::Vector2d& uv)
      : point(p), camera_from_root(g), intrinsics(k), target(uv) {}
  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    T uv[2];
    ProjectSkinnedPoint(point, camera_from_root, intrinsics, parameters, uv);
    residuals[0] = uv[0] - T(target[0]);
    residuals[1] = uv[1] - T(target[1]);
    return true;
  }
  const SkinnedPoint point;
  const Pose camera_from_root;
  const Eigen::Vector4d intrinsics;
  const Eigen::Vector2d target;
};

// Holds the distance image (a cv::Mat header: shared, reference-counted
// data) and the interpolator reading it, so it is neither copied nor moved.
struct SkinnedMaskResidual {
  SkinnedMaskResidual(const SkinnedPoint& p, const Pose& g, const Eigen::Vector4d& k,
                      const cv::Mat& d)
      : point(p),
        camera_from_root(g),
        intrinsics(k),
        distance(d),
        grid(distance.ptr<float>(), 0, distance.rows, 0, distance.cols),
        interpolator(grid) {}
  SkinnedMaskResidual(const SkinnedMaskResidual&) = delete;
  SkinnedMaskResidual& operator=(const SkinnedMaskResidual&) = delete;
  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    T uv[2];
    ProjectSkinnedPoint(point, camera_from_root, intrinsics, parameters, uv);
    // Pixel (i, j) holds the value at its centre (i + 0.5, j + 0.5).
    interpolator.Evaluate(uv[1] - T(0.5), uv[0] - T(0.5), residuals);
    return true;
  }
  const SkinnedPoint point;
  const Pose camera_from_root;
  const Eigen::Vector4d intrinsics;
  const cv::Mat distance;
  const ceres::Grid2D<float, 1> grid;
  const ceres::BiCubicInterpolator<ceres::Grid2D<float, 1>> interpolator;
};

// The pixel of a skinned point (ProjectSkinnedPoint) and, when d_uv is not
// null, its 2 x kPoseSize Jacobian with respect to each bone transform
// (d_uv->at(k) for point.bones[k]; quaternion columns first, as the
// parameter block). Rotations differentiate through Jet<4> on the
// quaternion alone; the blend, the root pose and the projection by hand.
// ProjectPoint clamps the depth at kMinProjectionDepth: there the depth's
// column is zero, as autodiff gives.
using PixelJacobian = Eigen::Matrix<double, 2, kPoseSize, Eigen::RowMajor>;
Eigen::Vector2d ProjectSkinnedPointWithJacobian(const SkinnedPoint& point,
                                                const Pose& camera_from_root,
                                                const Eigen::Vector4d& intrinsics,
                                                double const* const* parameters,
                                                std::vector<PixelJacobian>* d_uv) {
  Eigen::Vector2d uv;
  if (d_uv == nullptr) {  // values only: the templated projection
    ProjectSkinnedPoint(point, camera_from_root, intrinsics, parameters, uv.data());
    return uv;
  }
  using J4 = ceres::Jet<double, 4>;
  const int n = static_cast<int>(point.bones.size());
  Eigen::Vector3d blended = Eigen::Vector3d::Zero();
  std::vector<Eigen::Matrix<double, 3, 4>> d_q(n);
  const J4 x[3] = {J4(point.x[0]), J4(point.x[1]), J4(point.x[2])};
  for (int k = 0; k < n; ++k) {
    const double* pose = parameters[k];
    J4 q[4], z[3];
    for (int i = 0; i < 4; ++i) q[i] = J4(pose[kPoseQw + i], i);
    ceres::QuaternionRotatePoint(q, x, z);
    for (int i = 0; i < 3; ++i) {
      blended[i] += point.weights[k] * (z[i].a + pose[kPoseT + i]);
      d_q[k].row(i) = z[i].v.transpose();
    }
  }
  Eigen::Vector3d cam;
  PoseTransformPoint(camera_from_root.data(), blended.data(), cam.data());
  ProjectPoint(intrinsics.data(), cam.data(), uv.data());
  const bool clamped = cam.z() < kMinProjectionDepth;
  const double z = clamped ? kMinProjectionDepth : cam.z();
  Eigen::Matrix<double, 2, 3> d_cam;
  d_cam << intrinsics[0] / z, 0.0, clamped ? 0.0 : -intrinsics[0] * cam.x() / (z * z), 0.0,
      intrinsics[1] / z, clamped ? 0.0 : -intrinsics[1] * cam.y() / (z * z);
  double rotation[9];
  ceres::QuaternionToRotation(camera_from_root.data() + kPoseQw, rotation);  // row-major
  const Eigen::Matrix<double, 2, 3> d_blended =
      d_cam * Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(rotation);
  d_uv->resize(n);
  for (int k = 0; k < n; ++k) {
    PixelJacobian& jk = (*d_uv)[k];
    jk.block<2, 4>(0, kPoseQw) = point.weights[k] * d_blended * d_q[k];
    jk.block<2, 3>(0, kPoseT) = point.weights[k] * d_blended;
  }
  return uv;
}

// What the pixel and mask costs share: the point, one kPoseSize block per
// bone of it, its projection with Jacobians, and the chain rule from the
// residual's derivative with respect to the pixel (R x 2) to the blocks.
class SkinnedPointCost : public ceres::CostFunction {
 protected:
  SkinnedPointCost(const SkinnedPoint& p, const Pose& g, const Eigen::Vector4d& k, int residuals)
      : point_(p), camera_from_root_(g), intrinsics_(k) {
    set_num_residuals(residuals);
    for (size_t i = 0; i < point_.bones.size(); ++i) {
      mutable_parameter_block_sizes()->push_back(kPoseSize);
    }
  }
  Eigen::Vector2d Project(double const* const* parameters, std::vector<PixelJacobian>* d_uv) const {
    return ProjectSkinnedPointWithJacobian(point_, camera_from_root_, intrinsics_, parameters,
                                           d_uv);
  }
  template <int R>
  static void WriteJacobians(const Eigen::Matrix<double, R, 2>& d_r,
                             const std::vector<PixelJacobian>& d_uv, double** jacobians) {
    for (size_t k = 0; k < d_uv.size(); ++k) {
      if (jacobians[k] == nullptr) continue;
      Eigen::Map<Eigen::Matrix<double, R, kPoseSize, Eigen::RowMajor>> out(jacobians[k]);
      out = d_r * d_uv[k];
    }
  }

 private:
  const SkinnedPoint point_;
  const Pose camera_from_root_;
  const Eigen::Vector4d intrinsics_;
};

// The pixel residual (SkinnedPixelResidual) with the Jacobian above.
class SkinnedPixelCost : public SkinnedPointCost {
 public:
  SkinnedPixelCost(const SkinnedPoint& p, const Pose& g, const Eigen::Vector4d& k,
                   const Eigen::Vector2d& uv)
      : SkinnedPointCost(p, g, k, 2), target_(uv) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    std::vector<PixelJacobian> d_uv;
    const Eigen::Vector2d uv = Project(parameters, jacobians != nullptr ? &d_uv : nullptr);
    residuals[0] = uv.x() - target_.x();
    residuals[1] = uv.y() - target_.y();
    if (jacobians != nullptr) WriteJacobians<2>(Eigen::Matrix2d::Identity(), d_uv, jacobians);
    return true;
  }

 private:
  const Eigen::Vector2d target_;
};

// The mask residual (SkinnedMaskResidual) with the Jacobian above and the
// interpolator's gradient.
class SkinnedMaskCost : public SkinnedPointCost {
 public:
  SkinnedMaskCost(const SkinnedPoint& p, const Pose& g, const Eigen::Vector4d& k, const cv::Mat& d)
      : SkinnedPointCost(p, g, k, 1),
        distance_(d),
        grid_(distance_.ptr<float>(), 0, distance_.rows, 0, distance_.cols),
        interpolator_(grid_) {}
  SkinnedMaskCost(const SkinnedMaskCost&) = delete;
  SkinnedMaskCost& operator=(const SkinnedMaskCost&) = delete;
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    std::vector<PixelJacobian> d_uv;
    const Eigen::Vector2d uv = Project(parameters, jacobians != nullptr ? &d_uv : nullptr);
    double d_row = 0.0, d_col = 0.0;
    // Pixel (i, j) holds the value at its centre (i + 0.5, j + 0.5).
    interpolator_.Evaluate(uv.y() - 0.5, uv.x() - 0.5, residuals, &d_row, &d_col);
    if (jacobians != nullptr) {
      WriteJacobians<1>(Eigen::Matrix<double, 1, 2>(d_col, d_row), d_uv, jacobians);
    }
    return true;
  }

 private:
  const cv::Mat distance_;
  const ceres::Grid2D<float, 1> grid_;
  const ceres::BiCubicInterpolator<ceres::Grid2D<float, 1>> interpolator_;
};

struct BonePairResidual {
  template <typename T>
  bool operator()(const T* ja, const T* jb, T* residuals) const {
    const T x[3] = {T(m[0]), T(m[1]), T(m[2])};
    T ya[3], yb[3];
    PoseTransformPoint(ja, x, ya);
    PoseTransformPoint(jb, x, yb);
    for (int i = 0; i < 3; ++i) residuals[i] = T(scale) * (ya[i] - yb[i]);
    return true;
  }
  Eigen::Vector3d m;
  double scale;
};

// All of a bone pair's shared points at once, through four homogeneous
// points (p_k, w_k): r_k = scale (R_a p_k + w_k t_a - R_b p_k - w_k t_b)
// (MakeBonePairMomentCostFunction).
struct BonePairMomentResidual {
  template <typename T>
  bool operator()(const T* ja, const T* jb, T* residuals) const {
    for (int k = 0; k < 4; ++k) {
      const T p[3] = {T(points(0, k)), T(points(1, k)), T(points(2, k))};
      const T w(points(3, k));
      T ya[3], yb[3];
      ceres::QuaternionRotatePoint(ja + kPoseQw, p, ya);
      ceres::QuaternionRotatePoint(jb + kPoseQw, p, yb);
      for (int i = 0; i < 3; ++i) {
        residuals[3 * k + i] = T(scale) * (ya[i] - yb[i] + w * (ja[kPoseT + i] - jb[kPoseT + i]));
      }
    }
    return true;
  }
  Eigen::Matrix4d points;  // columns (p_k, w_k)
  double scale;
};

// A bone transform's travel of its rest centre c: R c + t - c.
template <typename T>
void CentreTravel(const T* pose, const Eigen::Vector3d& c, T* tau) {
  const T x[3] = {T(c[0]), T(c[1]), T(c[2])};
  PoseTransformPoint(pose, x, tau);
  for (int i = 0; i < 3; ++i) tau[i] -= T(c[i]);
}

struct BonePriorResidual {
  BonePriorResidual(const Pose& r, const Eigen::Vector3d& c, double s)
      : reference(r), centre(c), scale(s) {
    CentreTravel(reference.data(), centre, reference_travel.data());
  }
  template <typename T>
  bool operator()(const T* pose, T* residuals) const {
    // R R0^T as quaternions: q conj(q0), both normalised.
    using std::sqrt;
    const T norm =
        sqrt(pose[0] * pose[0] + pose[1] * pose[1] + pose[2] * pose[2] + pose[3] * pose[3]);
    const T q[4] = {pose[0] / norm, pose[1] / norm, pose[2] / norm, pose[3] / norm};
    const double n0 = reference.head<4>().norm();
    const T q0_conj[4] = {T(reference[0] / n0), T(-reference[1] / n0), T(-reference[2] / n0),
                          T(-reference[3] / n0)};
    T d[4], angle_axis[3], tau[3];
    ceres::QuaternionProduct(q, q0_conj, d);
    if (d[0] < T(0)) {
      for (T& e : d) e = -e;  // the short way round
    }
    ceres::QuaternionToAngleAxis(d, angle_axis);
    CentreTravel(pose, centre, tau);
    for (int i = 0; i < 3; ++i) {
      residuals[i] = T(scale) * angle_axis[i];
      residuals[3 + i] = T(scale) * (tau[i] - T(reference_travel[i]));
    }
    return true;
  }
  const Pose reference;
  const Eigen::Vector3d centre;
  const double scale;
  Eigen::Vector3d reference_travel;
};

// Pixel (i, j) of a projected point (u in [i, i + 1)), or false outside.
bool PixelOf(const Eigen::Vector4d& k, const Eigen::Vector3d& p, int width, int height,
             Eigen::Vector2i* pixel) {
  if (!(p.z() > kMinProjectionDepth)) return false;
  Eigen::Vector2d uv;
  ProjectPoint(k.data(), p.data(), uv.data());
  if (!(uv.x() >= 0 && uv.y() >= 0 && uv.x() < width && uv.y() < height)) return false;
  *pixel = uv.cast<int>();
  return true;
}

// The frame's surface vertices in its camera coordinates (the model's
// forward warp and root pose).
Eigen::Matrix3Xd PosedSurface(const Model& model, const Eigen::Matrix3Xd& surface, int video,
                              int frame) {
  TriangleMesh mesh;
  mesh.vertices = surface;
  return ArticulateMesh(model, mesh, video, frame).vertices;
}

bool Usable(const Frame& f) { return !f.skip && !f.features.empty(); }

}  // namespace

SkinnedPoint MakeSkinnedPoint(const Eigen::Vector3d& x, const Eigen::VectorXd& w) {
  SkinnedPoint p;
  p.x = x;
  double sum = 0.0;
  for (int b = 0; b < w.size(); ++b) {
    if (w[b] >= kRegistrationWeightCutoff) {
      p.bones.push_back(b);
      p.weights.push_back(w[b]);
      sum += w[b];
    }
  }
  CHECK(!p.bones.empty()) << "skinning weights sum to " << w.sum() << ", expected 1";
  for (double& v : p.weights) v /= sum;
  return p;
}

namespace {

// The point checks of every skinned-residual maker.
void CheckSkinnedPoint(const SkinnedPoint& point) {
  CHECK(!point.bones.empty());
  CHECK_EQ(point.bones.size(), point.weights.size());
}

// The mask makers' distance map (MaskOutsideDistance's): read as contiguous floats.
void CheckMaskDistance(const cv::Mat& distance) {
  CHECK_EQ(distance.type(), CV_32FC1);
  CHECK(distance.isContinuous());
}

// An autodiff twin's cost: one pose block per bone of the point.
template <class Residual>
std::unique_ptr<ceres::CostFunction> SkinnedAutoDiffCost(Residual* residual, int num_bones,
                                                         int num_residuals) {
  auto cost = std::make_unique<ceres::DynamicAutoDiffCostFunction<Residual, 14>>(residual);
  for (int k = 0; k < num_bones; ++k) cost->AddParameterBlock(kPoseSize);
  cost->SetNumResiduals(num_residuals);
  return cost;
}

}  // namespace

std::unique_ptr<ceres::CostFunction> MakeSkinnedPixelCostFunction(const SkinnedPoint& point,
                                                                  const Pose& camera_from_root,
                                                                  const Eigen::Vector4d& intrinsics,
                                                                  const Eigen::Vector2d& target) {
  CheckSkinnedPoint(point);
  return std::make_unique<SkinnedPixelCost>(point, camera_from_root, intrinsics, target);
}

std::unique_ptr<ceres::CostFunction> MakeSkinnedPixelCostFunctionAutoDiff(
    const SkinnedPoint& point, const Pose& camera_from_root, const Eigen::Vector4d& intrinsics,
    const Eigen::Vector2d& target) {
  CheckSkinnedPoint(point);
  return SkinnedAutoDiffCost(new SkinnedPixelResidual(point, camera_from_root, intrinsics, target),
                             static_cast<int>(point.bones.size()), 2);
}

cv::Mat MaskOutsideDistance(const cv::Mat& mask) {
  CHECK_EQ(mask.type(), CV_8UC1);
  // Zero where the distance is 0 (object, ignored), non-zero elsewhere.
  const cv::Mat outside = mask == kMaskBackground;
  if (cv::countNonZero(outside) == static_cast<int>(mask.total())) return cv::Mat();
  cv::Mat distance;
  cv::distanceTransform(outside, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  return distance;
}

std::unique_ptr<ceres::CostFunction> MakeSkinnedMaskCostFunction(const SkinnedPoint& point,
                                                                 const Pose& camera_from_root,
                                                                 const Eigen::Vector4d& intrinsics,
                                                                 const cv::Mat& distance) {
  CheckSkinnedPoint(point);
  CheckMaskDistance(distance);
  return std::make_unique<SkinnedMaskCost>(point, camera_from_root, intrinsics, distance);
}

std::unique_ptr<ceres::CostFunction> MakeSkinnedMaskCostFunctionAutoDiff(
    const SkinnedPoint& point, const Pose& camera_from_root, const Eigen::Vector4d& intrinsics,
    const cv::Mat& distance) {
  CheckSkinnedPoint(point);
  CheckMaskDistance(distance);
  return SkinnedAutoDiffCost(new SkinnedMaskResidual(point, camera_from_root, intrinsics, distance),
                             static_cast<int>(point.bones.size()), 1);
}

std::unique_ptr<ceres::CostFunction> MakeBonePairCostFunction(const Eigen::Vector3d& m,
                                                              double scale) {
  return std::make_unique<ceres::AutoDiffCostFunction<BonePairResidual, 3, kPoseSize, kPoseSize>>(
      new BonePairResidual{m, scale});
}

std::unique_ptr<ceres::CostFunction> MakeBonePairMomentCostFunction(
    const std::vector<Eigen::Vector3d>& points, double scale) {
  CHECK(!points.empty());
  // M = sum_m [m; 1][m; 1]^T = V diag(lambda) V^T; the columns of
  // V diag(sqrt(lambda)) (lambda clamped at 0: M is positive semidefinite,
  // rounding aside) give sum_k x_k x_k^T = M.
  Eigen::Matrix4d moments = Eigen::Matrix4d::Zero();
  for (const Eigen::Vector3d& m : points) {
    const Eigen::Vector4d x(m.x(), m.y(), m.z(), 1.0);
    moments.noalias() += x * x.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eigen(moments);
  CHECK_EQ(eigen.info(), Eigen::Success);
  const Eigen::Vector4d root = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  auto* residual = new BonePairMomentResidual{eigen.eigenvectors() * root.asDiagonal(), scale};
  return std::make_unique<
      ceres::AutoDiffCostFunction<BonePairMomentResidual, 12, kPoseSize, kPoseSize>>(residual);
}

std::unique_ptr<ceres::CostFunction> MakeBonePriorCostFunction(const Pose& reference,
                                                               const Eigen::Vector3d& centre,
                                                               double scale) {
  return std::make_unique<ceres::AutoDiffCostFunction<BonePriorResidual, 6, kPoseSize>>(
      new BonePriorResidual(reference, centre, scale));
}

RegistrationProxy MakeRegistrationProxy(const Eigen::Matrix3Xd& surface,
                                        const Eigen::MatrixXd& weights, int count,
                                        double joint_min_weight, int joint_points,
                                        std::uint32_t seed) {
  CHECK_EQ(weights.cols(), surface.cols());
  CHECK_GT(count, 0);
  RegistrationProxy proxy;
  proxy.surface = surface;
  const int n = static_cast<int>(surface.cols());
  std::vector<int> all(n);
  std::iota(all.begin(), all.end(), 0);
  std::mt19937 rng(seed);
  std::shuffle(all.begin(), all.end(), rng);
  all.resize(std::min(n, count));
  std::sort(all.begin(), all.end());
  proxy.subset = all;
  for (int i : proxy.subset)
    proxy.points.push_back(MakeSkinnedPoint(surface.col(i), weights.col(i)));
  const int B = static_cast<int>(weights.rows());
  for (int a = 0; a < B; ++a) {
    for (int b = a + 1; b < B; ++b) {
      RegistrationProxy::Pair pair{a, b, {}};
      for (int i : proxy.subset) {
        if (static_cast<int>(pair.points.size()) >= joint_points) break;
        if (weights(a, i) > joint_min_weight && weights(b, i) > joint_min_weight) {
          pair.points.push_back(surface.col(i));
        }
      }
      if (!pair.points.empty()) proxy.pairs.push_back(std::move(pair));
    }
  }
  return proxy;
}

std::vector<int> VisiblePoints(const Eigen::Matrix3Xd& points_in_camera,
                               const Eigen::Vector4d& intrinsics, int width, int height,
                               double tolerance, std::vector<Eigen::Vector2i>* pixels) {
  const int n = static_cast<int>(points_in_camera.cols());
  std::vector<double> depth(static_cast<size_t>(width) * height,
                            std::numeric_limits<double>::infinity());
  std::vector<Eigen::Vector2i> at(n);
  std::vector<char> inside(n, 0);
  for (int i = 0; i < n; ++i) {
    inside[i] = PixelOf(intrinsics, points_in_camera.col(i), width, height, &at[i]);
    if (!inside[i]) continue;
    double& d = depth[static_cast<size_t>(at[i].y()) * width + at[i].x()];
    d = std::min(d, points_in_camera(2, i));
  }
  std::vector<int> visible;
  if (pixels != nullptr) pixels->clear();
  for (int i = 0; i < n; ++i) {
    if (!inside[i]) continue;
    if (points_in_camera(2, i) >
        depth[static_cast<size_t>(at[i].y()) * width + at[i].x()] + tolerance) {
      continue;
    }
    visible.push_back(i);
    if (pixels != nullptr) pixels->push_back(at[i]);
  }
  return visible;
}

Eigen::MatrixXd MeanFeatureEmbedding(const Model& model, const Dataset& dataset,
                                     const RegistrationProxy& proxy, double tolerance) {
  CHECK_EQ(static_cast<int>(dataset.videos.size()), model.num_videos());
  const int n = static_cast<int>(proxy.subset.size());
  // Position of each surface vertex in the subset (-1: not fitted).
  std::vector<int> position(proxy.surface.cols(), -1);
  for (int k = 0; k < n; ++k) position[proxy.subset[k]] = k;
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(kFeatureDim, n);
  for (int v = 0; v < model.num_videos(); ++v) {
    const Video& video = dataset.videos[v];
    for (int t = 0; t < static_cast<int>(video.frames.size()); ++t) {
      const Frame& f = video.frames[t];
      if (!Usable(f)) continue;
      std::vector<Eigen::Vector2i> pixels;
      const std::vector<int> visible =
          VisiblePoints(PosedSurface(model, proxy.surface, v, t), model.video(v).intrinsics,
                        f.mask.cols, f.mask.rows, tolerance, &pixels);
      for (size_t j = 0; j < visible.size(); ++j) {
        const int k = position[visible[j]];
        const Eigen::Vector2i& p = pixels[j];
        if (k < 0 || f.mask.at<unsigned char>(p.y(), p.x()) != kMaskObject) continue;
        const cv::float16_t* feat = f.features.ptr<cv::float16_t>(p.y()) + kFeatureDim * p.x();
        for (int c = 0; c < kFeatureDim; ++c) sum(c, k) += static_cast<float>(feat[c]);
      }
    }
  }
  for (int k = 0; k < n; ++k) {
    const double norm = sum.col(k).norm();
    if (norm > 1e-12) sum.col(k) /= norm;
  }
  return sum;
}

FrameMatches MatchFrameFeatures(const Eigen::MatrixXd& embedding, const Frame& frame, int count,
                                std::uint32_t seed) {
  CHECK_EQ(embedding.rows(), kFeatureDim);
  FrameMatches matches;
  if (frame.features.empty() || embedding.cols() == 0) return matches;
  std::vector<Eigen::Vector2i> object;
  for (int y = 0; y < frame.mask.rows; ++y) {
    const unsigned char* row = frame.mask.ptr<unsigned char>(y);
    for (int x = 0; x < frame.mask.cols; ++x) {
      if (row[x] == kMaskObject) object.emplace_back(x, y);
    }
  }
  if (static_cast<int>(object.size()) > count) {
    std::mt19937 rng(seed);
    std::shuffle(object.begin(), object.end(), rng);
    object.resize(count);
  }
  Eigen::Matrix<double, kFeatureDim, 1> f;
  for (const Eigen::Vector2i& p : object) {
    const cv::float16_t* feat = frame.features.ptr<cv::float16_t>(p.y()) + kFeatureDim * p.x();
    if (!IsPixelFeature(feat)) continue;
    for (int c = 0; c < kFeatureDim; ++c) f[c] = static_cast<float>(feat[c]);
    int best = -1;
    (embedding.transpose() * f).maxCoeff(&best);
    matches.vertex.push_back(best);
    matches.pixel.emplace_back(p.x() + 0.5, p.y() + 0.5);
  }
  return matches;
}

namespace {

// One frame's registration problem (RegisterFrameBones): the frame's bone
// transforms as parameter blocks and the terms of step 4, added in a fixed
// order (the order of Ceres' residual blocks fixes its sums' rounding).
class FrameFit {
 public:
  FrameFit(const FrameRegistrationInputs& in, const BoneRegistrationConfig& config, double* bones_t)
      : in_(in), config_(config), bones_t_(bones_t), problem_(ProblemOptions()) {
    CHECK_GT(in.num_bones, 0);
    for (int b = 0; b < in.num_bones; ++b) {
      problem_.AddParameterBlock(
          Block(b), kPoseSize,
          MakeStackedPivotPoseManifold(1, in.bones + kBoneSize * b, kBoneSize, kBoneCenter)
              .release());
    }
    // Pixels per model unit at the root's depth: the joint and prior
    // residuals in the matches' units.
    scale_ = in.intrinsics[0] / std::max(in.camera_from_root[kPoseT + 2], kMinProjectionDepth);
  }

  // The match, mask, joint and prior terms (not the coverage ties).
  void AddTerms() {
    AddMatchTerms();
    AddMaskTerms();
    AddJointTerms();
    AddPriorTerms();
  }

  // With in.alternative_start: starts from it when the terms cost less there
  // (the coverage ties, made from the start, are not added yet).
  bool ChooseStart() {
    if (in_.alternative_start == nullptr) return false;
    const int size = kPoseSize * in_.num_bones;
    const std::vector<double> own(bones_t_, bones_t_ + size);
    const double own_cost = Cost();
    std::copy(in_.alternative_start, in_.alternative_start + size, bones_t_);
    if (Cost() < own_cost) return true;
    std::copy(own.begin(), own.end(), bones_t_);
    return false;
  }

  double MedianMatchPx() {
    std::vector<double> norms;
    for (ceres::ResidualBlockId id : match_blocks_) {
      double r[2];
      problem_.EvaluateResidualBlock(id, false, nullptr, r, nullptr);
      norms.push_back(std::hypot(r[0], r[1]));
    }
    return norms.empty() ? 0.0 : Median(norms);
  }

  bool HasCoverage() const {
    return config_.coverage_weight > 0 && in_.silhouette != nullptr &&
           !in_.silhouette->object_pixels.empty() && !in_.proxy->points.empty();
  }

  // 2D ICP: each object pixel tied to the nearest projection under the
  // current fit, the previous round's ties removed (a fresh loss each
  // round: removing a round's blocks deletes the loss they share).
  void TieCoverage() {
    for (ceres::ResidualBlockId id : coverage_blocks_) problem_.RemoveResidualBlock(id);
    coverage_blocks_.clear();
    const std::vector<SkinnedPoint>& points = in_.proxy->points;
    const std::vector<Eigen::Vector2d>& pixels = in_.silhouette->object_pixels;
    // The projections as points of the plane z = 0 of an exact kd-tree
    // (a brute-force search was 128 ms a frame at 10 rounds, 13,266
    // vertices and 500 pixels).
    Eigen::Matrix3Xd projected = Eigen::Matrix3Xd::Zero(3, points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      const SkinnedPoint& p = points[i];
      std::vector<const double*> blocks;
      for (int b : p.bones) blocks.push_back(Block(b));
      double uv[2];
      ProjectSkinnedPoint(p, in_.camera_from_root, in_.intrinsics, blocks.data(), uv);
      projected(0, i) = uv[0];
      projected(1, i) = uv[1];
    }
    const KdTree3 tree(projected);
    auto* loss =
        new ceres::ScaledLoss(new ceres::HuberLoss(config_.huber_px),
                              config_.coverage_weight / pixels.size(), ceres::TAKE_OWNERSHIP);
    for (const Eigen::Vector2d& q : pixels) {
      const SkinnedPoint& p = points[tree.Nearest(Eigen::Vector3d(q.x(), q.y(), 0.0))];
      coverage_blocks_.push_back(problem_.AddResidualBlock(
          MakeSkinnedPixelCostFunction(p, in_.camera_from_root, in_.intrinsics, q).release(), loss,
          Blocks(p)));
    }
  }

  ceres::Problem& problem() { return problem_; }

 private:
  static ceres::Problem::Options ProblemOptions() {
    ceres::Problem::Options options;
    options.enable_fast_removal = true;  // the coverage ties are remade each round
    return options;
  }
  double* Block(int b) const { return bones_t_ + kPoseSize * b; }
  std::vector<double*> Blocks(const SkinnedPoint& p) const {
    std::vector<double*> blocks;
    for (int b : p.bones) blocks.push_back(Block(b));
    return blocks;
  }
  double Cost() {
    double cost = 0.0;
    problem_.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
    return cost;
  }

  void AddMatchTerms() {
    const FrameMatches& matches = *in_.matches;
    const int n = static_cast<int>(matches.vertex.size());
    if (n == 0) return;
    auto* loss = new ceres::ScaledLoss(new ceres::HuberLoss(config_.huber_px),
                                       config_.match_weight / n, ceres::TAKE_OWNERSHIP);
    for (int i = 0; i < n; ++i) {
      const SkinnedPoint& p = in_.proxy->points[matches.vertex[i]];
      match_blocks_.push_back(problem_.AddResidualBlock(
          MakeSkinnedPixelCostFunction(p, in_.camera_from_root, in_.intrinsics, matches.pixel[i])
              .release(),
          loss, Blocks(p)));
    }
  }

  void AddMaskTerms() {
    const cv::Mat* distance =
        in_.silhouette != nullptr ? &in_.silhouette->outside_distance : nullptr;
    const std::vector<SkinnedPoint>& points = in_.proxy->points;
    if (config_.mask_weight <= 0 || distance == nullptr || distance->empty() || points.empty()) {
      return;
    }
    // Every stride-th fitted vertex (the proxy's are a random subset).
    const int total = static_cast<int>(points.size());
    const int stride = std::max(1, (total + config_.mask_points - 1) / config_.mask_points);
    const int m = (total + stride - 1) / stride;
    auto* loss = new ceres::ScaledLoss(new ceres::HuberLoss(config_.huber_px),
                                       config_.mask_weight / m, ceres::TAKE_OWNERSHIP);
    for (int i = 0; i < total; i += stride) {
      problem_.AddResidualBlock(
          MakeSkinnedMaskCostFunction(points[i], in_.camera_from_root, in_.intrinsics, *distance)
              .release(),
          loss, Blocks(points[i]));
    }
  }

  void AddJointTerms() {
    int shared = 0;
    for (const RegistrationProxy::Pair& pair : in_.proxy->pairs) shared += pair.points.size();
    if (config_.joint_weight <= 0 || shared == 0) return;
    // One block per pair: the same sum of squares as a block per shared
    // point (MakeBonePairMomentCostFunction), 12 rows instead of 3 a point.
    const double s = std::sqrt(config_.joint_weight / shared) * scale_;
    for (const RegistrationProxy::Pair& pair : in_.proxy->pairs) {
      problem_.AddResidualBlock(MakeBonePairMomentCostFunction(pair.points, s).release(), nullptr,
                                Block(pair.a), Block(pair.b));
    }
  }

  void AddPriorTerms() {
    const int B = in_.num_bones;
    for (int b = 0; b < B; ++b) {
      const Eigen::Vector3d c(in_.bones + kBoneSize * b + kBoneCenter);
      const Pose reference = in_.previous != nullptr
                                 ? Pose(Eigen::Map<const Pose>(in_.previous + kPoseSize * b))
                                 : PoseIdentity();
      if (config_.smooth_weight > 0) {
        problem_.AddResidualBlock(
            MakeBonePriorCostFunction(reference, c, std::sqrt(config_.smooth_weight / B) * scale_)
                .release(),
            nullptr, Block(b));
      }
      if (config_.rest_weight > 0) {
        problem_.AddResidualBlock(
            MakeBonePriorCostFunction(PoseIdentity(), c,
                                      std::sqrt(config_.rest_weight / B) * scale_)
                .release(),
            nullptr, Block(b));
      }
    }
  }

  const FrameRegistrationInputs& in_;
  const BoneRegistrationConfig& config_;
  double* bones_t_;
  ceres::Problem problem_;
  double scale_ = 0.0;
  std::vector<ceres::ResidualBlockId> match_blocks_;
  std::vector<ceres::ResidualBlockId> coverage_blocks_;
};

}  // namespace

FrameRegistration RegisterFrameBones(const FrameRegistrationInputs& in,
                                     const BoneRegistrationConfig& config, double* bones_t) {
  FrameFit fit(in, config, bones_t);
  fit.AddTerms();
  FrameRegistration out;
  out.started_from_alternative = fit.ChooseStart();
  out.median_match_px_before = fit.MedianMatchPx();
  const bool coverage = fit.HasCoverage();
  const int rounds = coverage ? config.coverage_rounds : 1;
  ceres::Solver::Options options;
  options.max_num_iterations = std::max(1, (config.iterations + rounds - 1) / rounds);
  // Dense normal equations: 6 B unknowns (96 on the default scene), where
  // the sparse ones rebuilt their symbolic structure at each of the
  // coverage rounds' solves (the default scene's stage-3 registration, one
  // thread: 40.6 s against 43.9 with SPARSE_NORMAL_CHOLESKY, the same fit
  // to the printed digits; DENSE_QR was slower than both, 44 s against 32
  // with the mask term alone).
  options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  for (int round = 0; round < rounds; ++round) {
    if (coverage) fit.TieCoverage();
    ceres::Solver::Summary summary;
    ceres::Solve(options, &fit.problem(), &summary);
    if (round == 0) out.initial_cost = summary.initial_cost;
    out.final_cost = summary.final_cost;
    out.iterations += static_cast<int>(summary.iterations.size()) - 1;
  }
  out.median_match_px_after = fit.MedianMatchPx();
  return out;
}

std::vector<Eigen::Vector2d> SampleObjectPixels(const cv::Mat& mask, int count,
                                                std::uint32_t seed) {
  CHECK_EQ(mask.type(), CV_8UC1);
  std::vector<Eigen::Vector2d> object;
  for (int y = 0; y < mask.rows; ++y) {
    const unsigned char* row = mask.ptr<unsigned char>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (row[x] == kMaskObject) object.emplace_back(x + 0.5, y + 0.5);
    }
  }
  if (static_cast<int>(object.size()) > count) {
    std::mt19937 rng(seed);
    std::shuffle(object.begin(), object.end(), rng);
    object.resize(count);
  }
  return object;
}

std::string BoneRegistrationReport::Describe() const {
  if (!registered) return "bone registration skipped: " + reason;
  char text[320];
  std::snprintf(text, sizeof(text),
                "bone registration: %d frames on %d surface vertices (%d bone pairs) in %.1f s; "
                "median match %.2f -> %.2f px; bones turned %.1f deg on average",
                frames, surface_vertices, pairs, seconds, median_match_px_before,
                median_match_px_after, mean_turn_deg);
  std::string out = text;
  if (own_starts >= 0) {
    out += "; " + std::to_string(own_starts) +
           " frames started from their own motion rather than the previous frame's fit";
  }
  return out;
}

BoneRegistrationReport RegisterBoneMotion(Model* model, const Dataset& dataset,
                                          const Eigen::AlignedBox3d& bounds,
                                          const BoneRegistrationConfig& config,
                                          std::uint32_t seed) {
  Timer timer;
  BoneRegistrationReport report;
  CHECK_EQ(static_cast<int>(dataset.videos.size()), model->num_videos());
  const int B = model->num_bones();
  if (B == 0) {
    report.reason = "the model has no bones";
    return report;
  }
  if (!dataset.HasPixelFeatures()) {
    report.reason = "no frame has pixel features";
    return report;
  }
  ExtractOptions options;
  options.grid.resolution = config.resolution;
  options.grid.bounds_min = bounds.min();
  options.grid.bounds_max = bounds.max();
  TriangleMesh mesh;
  try {
    mesh = ExtractCanonicalMesh(*model, options);
  } catch (const InputError& e) {
    report.reason = std::string("no surface (") + e.what() + ")";
    return report;
  }
  if (mesh.NumVertices() == 0) {
    // A density that fits the masks without an SDF zero crossing (very
    // rough root poses): nothing to register.
    report.reason = "no surface (the canonical SDF has no zero crossing in the bounds)";
    return report;
  }
  const RegistrationProxy proxy =
      MakeRegistrationProxy(mesh.vertices, SkinningWeightsAt(*model, mesh.vertices),
                            config.vertices, config.joint_min_weight, config.joint_points, seed);
  report.surface_vertices = static_cast<int>(mesh.vertices.cols());
  report.pairs = static_cast<int>(proxy.pairs.size());
  const Eigen::MatrixXd embedding =
      MeanFeatureEmbedding(*model, dataset, proxy, config.visible_tolerance);

  // Frames of a video in order, each started as config.start says; videos
  // in parallel (each writes only its own frames' bones_t and results).
  const int V = model->num_videos();
  std::vector<int> first(V + 1, 0);
  for (int v = 0; v < V; ++v) first[v + 1] = first[v] + dataset.videos[v].frames.size();
  std::vector<FrameRegistration> results(first[V]);
  std::vector<char> done(first[V], 0);
  ParallelFor(V, [&](int begin, int end) {
    for (int v = begin; v < end; ++v) {
      const double* previous = nullptr;
      for (int t = 0; t < static_cast<int>(dataset.videos[v].frames.size()); ++t) {
        const Frame& f = dataset.videos[v].frames[t];
        double* bones_t = model->frame(v, t).bones_t.data();
        if (!Usable(f)) continue;
        const int k = first[v] + t;
        const FrameMatches matches = MatchFrameFeatures(
            embedding, f, config.match_pixels, seed + 7919u * static_cast<std::uint32_t>(k + 1));
        // The start: the previous fit, the frame's own transforms, or the
        // cheaper (RegisterFrameBones' alternative_start).
        const double* alternative = nullptr;
        if (previous != nullptr && config.start == RegistrationStart::kPrevious) {
          std::copy(previous, previous + kPoseSize * B, bones_t);
        } else if (config.start == RegistrationStart::kLowerCost) {
          alternative = previous;
        }
        FrameSilhouette silhouette;
        if (config.mask_weight > 0) silhouette.outside_distance = MaskOutsideDistance(f.mask);
        if (config.coverage_weight > 0) {
          silhouette.object_pixels = SampleObjectPixels(
              f.mask, config.coverage_pixels, seed + 104729u * static_cast<std::uint32_t>(k + 1));
        }
        FrameRegistrationInputs in;
        in.proxy = &proxy;
        in.matches = &matches;
        in.num_bones = B;
        in.bones = model->bones();
        in.camera_from_root = model->RootPose(v, t);
        in.intrinsics = model->video(v).intrinsics;
        in.previous = previous;
        in.silhouette = &silhouette;
        in.alternative_start = alternative;
        results[k] = RegisterFrameBones(in, config, bones_t);
        done[k] = 1;
        previous = bones_t;
      }
    }
  });
  std::vector<double> before, after;
  double turn = 0.0;
  int own = 0;
  for (int v = 0; v < V; ++v) {
    bool had_previous = false;  // lower_cost offered this frame the previous fit
    for (int t = 0; t < static_cast<int>(dataset.videos[v].frames.size()); ++t) {
      const int k = first[v] + t;
      if (!done[k]) continue;
      ++report.frames;
      if (had_previous && !results[k].started_from_alternative) ++own;
      had_previous = true;
      before.push_back(results[k].median_match_px_before);
      after.push_back(results[k].median_match_px_after);
      const double* bones_t = model->frame(v, t).bones_t.data();
      const Pose identity = PoseIdentity();
      for (int b = 0; b < B; ++b) {
        turn += RotationAngleBetween(bones_t + kPoseSize * b, identity.data()) * 180.0 / M_PI / B;
      }
    }
  }
  if (report.frames == 0) {
    report.reason = "no usable frame";
    return report;
  }
  report.registered = true;
  report.median_match_px_before = Median(before);
  report.median_match_px_after = Median(after);
  report.mean_turn_deg = turn / report.frames;
  if (config.start == RegistrationStart::kLowerCost) report.own_starts = own;
  report.seconds = timer.Seconds();
  return report;
}

}  // namespace banmo
