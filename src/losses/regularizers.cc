#include "banmo/losses/regularizers.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/dynamic_autodiff_cost_function.h>
#include <ceres/jet.h>

#include <cmath>
#include <utility>
#include <vector>

#include "banmo/deform/bones.h"
#include "banmo/losses/bone_inside_loss.h"
#include "banmo/losses/eikonal_loss.h"
#include "banmo/losses/pose_smoothness_loss.h"
#include "banmo/util/dual.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

std::vector<int> OneGroupPerColumn(int n) {
  std::vector<int> groups(n + 1);
  for (int i = 0; i <= n; ++i) groups[i] = i;
  return groups;
}

class EikonalCostFunction final : public ceres::CostFunction {
 public:
  EikonalCostFunction(const CanonicalField& field, const Eigen::Matrix3Xd& points, double weight)
      : field_(field), points_(points), loss_(weight) {
    set_num_residuals(static_cast<int>(points.cols()));
    mutable_parameter_block_sizes()->push_back(field.SdfParameterSize());
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int n = static_cast<int>(points_.cols());
    FieldBatch batch;
    batch.x = points_;
    batch.view_dir = Eigen::Matrix3Xd::Zero(3, n);
    batch.appearance = Eigen::MatrixXd::Zero(field_.AppearanceCodeDim(), n);
    // The SDF gradient is the input Jacobian of the forward pass.
    field_.ForwardBatch(parameters[0], unused_color_.data(), &batch, /*input_jacobians=*/true);
    Eigen::Matrix3Xd c(3, n);
    for (int j = 0; j < n; ++j) {
      using J = ceres::Jet<double, 3>;
      const Eigen::Vector3d g = batch.dsdf_dx.col(j);
      const J gj[3] = {J(g[0], 0), J(g[1], 1), J(g[2], 2)};
      J r;
      loss_(gj, &r);
      residuals[j] = r.a;
      c.col(j) = r.v;  // d residual / d grad
    }
    if (jacobians == nullptr || jacobians[0] == nullptr) return true;
    Eigen::MatrixXd d_params;
    field_.SdfGradientBackward(parameters[0], batch, c, OneGroupPerColumn(n), &d_params);
    Eigen::Map<RowMajorMatrix>(jacobians[0], n, field_.SdfParameterSize()) = d_params.transpose();
    return true;
  }

 private:
  const CanonicalField& field_;
  const Eigen::Matrix3Xd points_;
  const EikonalLoss loss_;
  // The batched pass also runs the colour MLP; its output is not used here.
  const std::vector<double> unused_color_ = std::vector<double>(field_.ColorParameterSize(), 0.0);
};

class EikonalReference {
 public:
  EikonalReference(const CanonicalField& field, const Eigen::Matrix3Xd& points, double weight)
      : field_(field), points_(points), loss_(weight) {}

  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    // The SDF gradient by dual numbers over T: one directional derivative
    // per axis, each still a Jet over every weight.
    using D = Dual<T>;
    for (int j = 0; j < points_.cols(); ++j) {
      T g[3];
      for (int axis = 0; axis < 3; ++axis) {
        D x[3];
        for (int k = 0; k < 3; ++k) x[k] = D(T(points_(k, j)), T(k == axis ? 1.0 : 0.0));
        D sdf;
        field_.EvaluateSdf(parameters[0], x, &sdf, static_cast<D*>(nullptr));
        g[axis] = sdf.tangent;
      }
      loss_(g, &residuals[j]);
    }
    return true;
  }

 private:
  const CanonicalField& field_;
  const Eigen::Matrix3Xd points_;
  const EikonalLoss loss_;
};

class BoneInsideCostFunction final : public ceres::CostFunction {
 public:
  BoneInsideCostFunction(const CanonicalField& field, int num_bones, double margin, double weight)
      : field_(field), num_bones_(num_bones), loss_(margin, weight) {
    set_num_residuals(num_bones);
    mutable_parameter_block_sizes()->push_back(field.SdfParameterSize());
    mutable_parameter_block_sizes()->push_back(kBoneSize * num_bones);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int n = num_bones_;
    FieldBatch batch;
    batch.x.resize(3, n);
    for (int b = 0; b < n; ++b) {
      batch.x.col(b) =
          Eigen::Map<const Eigen::Vector3d>(parameters[1] + kBoneSize * b + kBoneCenter);
    }
    batch.view_dir = Eigen::Matrix3Xd::Zero(3, n);
    batch.appearance = Eigen::MatrixXd::Zero(field_.AppearanceCodeDim(), n);
    const bool want = jacobians != nullptr;
    field_.ForwardBatch(parameters[0], unused_color_.data(), &batch, want);
    Eigen::VectorXd slope(n);
    for (int b = 0; b < n; ++b) {
      using J = ceres::Jet<double, 1>;
      const J s(batch.sdf(b), 0);
      J r;
      loss_(&s, &r);
      residuals[b] = r.a;
      slope(b) = r.v[0];  // d residual / d sdf (0 or sqrt(w))
    }
    if (!want) return true;
    if (jacobians[0] != nullptr) {
      Eigen::MatrixXd d_params;
      field_.BackwardBatch(parameters[0], unused_color_.data(), batch, slope,
                           Eigen::Matrix3Xd::Zero(3, n), OneGroupPerColumn(n), &d_params, nullptr);
      Eigen::Map<RowMajorMatrix>(jacobians[0], n, field_.SdfParameterSize()) = d_params.transpose();
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<RowMajorMatrix> jac(jacobians[1], n, kBoneSize * n);
      jac.setZero();
      for (int b = 0; b < n; ++b) {
        jac.block<1, 3>(b, kBoneSize * b + kBoneCenter) =
            slope(b) * batch.dsdf_dx.col(b).transpose();
      }
    }
    return true;
  }

 private:
  const CanonicalField& field_;
  const int num_bones_;
  const BoneInsideLoss loss_;
  const std::vector<double> unused_color_ = std::vector<double>(field_.ColorParameterSize(), 0.0);
};

class BoneInsideReference {
 public:
  BoneInsideReference(const CanonicalField& field, int num_bones, double margin, double weight)
      : field_(field), num_bones_(num_bones), loss_(margin, weight) {}

  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    for (int b = 0; b < num_bones_; ++b) {
      T sdf;
      field_.EvaluateSdf(parameters[0], parameters[1] + kBoneSize * b + kBoneCenter, &sdf,
                         static_cast<T*>(nullptr));
      loss_(&sdf, &residuals[b]);
    }
    return true;
  }

 private:
  const CanonicalField& field_;
  const int num_bones_;
  const BoneInsideLoss loss_;
};

struct RootSmoothness {
  RootSmoothness(const Pose& a, const Pose& b, double wr, double wt)
      : init_a(a), init_b(b), loss(wr, wt) {}
  template <typename T>
  bool operator()(const T* delta_a, const T* delta_b, T* residual) const {
    T ia[kPoseSize], ib[kPoseSize], pa[kPoseSize], pb[kPoseSize];
    for (int k = 0; k < kPoseSize; ++k) {
      ia[k] = T(init_a[k]);
      ib[k] = T(init_b[k]);
    }
    PoseCompose(ia, delta_a, pa);  // G^t = G0^t dG^t, as RootPose
    PoseCompose(ib, delta_b, pb);
    return loss(pa, pb, residual);
  }
  const Pose init_a, init_b;
  const PoseSmoothnessLoss loss;
};

struct BoneSmoothness {
  BoneSmoothness(int b, double wr, double wt) : num_bones(b), loss(wr, wt) {}
  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    for (int b = 0; b < num_bones; ++b) {
      loss(parameters[0] + kPoseSize * b, parameters[1] + kPoseSize * b, residuals + 6 * b);
    }
    return true;
  }
  const int num_bones;
  const PoseSmoothnessLoss loss;
};

struct BoneJointResidual {
  BoneJointResidual(std::vector<BoneJoint> j, double w)
      : joints(std::move(j)), sqrt_weight(std::sqrt(w)) {}
  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    const T* bones_t = parameters[0];
    for (size_t k = 0; k < joints.size(); ++k) {
      const BoneJoint& joint = joints[k];
      const T m[3] = {T(joint.point[0]), T(joint.point[1]), T(joint.point[2])};
      T ya[3], yb[3];
      PoseTransformPoint(bones_t + kPoseSize * joint.a, m, ya);
      PoseTransformPoint(bones_t + kPoseSize * joint.b, m, yb);
      for (int i = 0; i < 3; ++i) residuals[3 * k + i] = T(sqrt_weight) * (ya[i] - yb[i]);
    }
    return true;
  }
  const std::vector<BoneJoint> joints;
  const double sqrt_weight;
};

}  // namespace

std::unique_ptr<ceres::CostFunction> MakeEikonalCostFunction(const CanonicalField& field,
                                                             const Eigen::Matrix3Xd& points,
                                                             double weight) {
  return std::make_unique<EikonalCostFunction>(field, points, weight);
}

std::unique_ptr<ceres::CostFunction> MakeEikonalReferenceCostFunction(
    const CanonicalField& field, const Eigen::Matrix3Xd& points, double weight) {
  auto cost = std::make_unique<ceres::DynamicAutoDiffCostFunction<EikonalReference, 8>>(
      new EikonalReference(field, points, weight));
  cost->AddParameterBlock(field.SdfParameterSize());
  cost->SetNumResiduals(static_cast<int>(points.cols()));
  return cost;
}

std::unique_ptr<ceres::CostFunction> MakeBoneInsideCostFunction(const CanonicalField& field,
                                                                int num_bones, double margin,
                                                                double weight) {
  CHECK_GT(num_bones, 0);
  return std::make_unique<BoneInsideCostFunction>(field, num_bones, margin, weight);
}

std::unique_ptr<ceres::CostFunction> MakeBoneInsideReferenceCostFunction(
    const CanonicalField& field, int num_bones, double margin, double weight) {
  auto cost = std::make_unique<ceres::DynamicAutoDiffCostFunction<BoneInsideReference, 8>>(
      new BoneInsideReference(field, num_bones, margin, weight));
  cost->AddParameterBlock(field.SdfParameterSize());
  cost->AddParameterBlock(kBoneSize * num_bones);
  cost->SetNumResiduals(num_bones);
  return cost;
}

std::unique_ptr<ceres::CostFunction> MakeRootSmoothnessCostFunction(const Pose& root_init_a,
                                                                    const Pose& root_init_b,
                                                                    double rotation_weight,
                                                                    double translation_weight) {
  return std::make_unique<ceres::AutoDiffCostFunction<
      RootSmoothness, PoseSmoothnessLoss::kNumResiduals, kPoseSize, kPoseSize>>(
      new RootSmoothness(root_init_a, root_init_b, rotation_weight, translation_weight));
}

std::unique_ptr<ceres::CostFunction> MakeBoneSmoothnessCostFunction(int num_bones,
                                                                    double rotation_weight,
                                                                    double translation_weight) {
  CHECK_GT(num_bones, 0);
  auto cost = std::make_unique<ceres::DynamicAutoDiffCostFunction<BoneSmoothness, 14>>(
      new BoneSmoothness(num_bones, rotation_weight, translation_weight));
  cost->AddParameterBlock(kPoseSize * num_bones);
  cost->AddParameterBlock(kPoseSize * num_bones);
  cost->SetNumResiduals(PoseSmoothnessLoss::kNumResiduals * num_bones);
  return cost;
}

std::unique_ptr<ceres::CostFunction> MakeBoneJointCostFunction(int num_bones,
                                                               std::vector<BoneJoint> joints,
                                                               double weight) {
  CHECK_GT(num_bones, 0);
  CHECK(!joints.empty()) << "no bone joints";
  for (const BoneJoint& j : joints) {
    CHECK(j.a >= 0 && j.b >= 0 && j.a < num_bones && j.b < num_bones && j.a != j.b)
        << "joint (" << j.a << ", " << j.b << ") of " << num_bones << " bones";
  }
  const int residuals = 3 * static_cast<int>(joints.size());
  auto cost = std::make_unique<ceres::DynamicAutoDiffCostFunction<BoneJointResidual, 14>>(
      new BoneJointResidual(std::move(joints), weight));
  cost->AddParameterBlock(kPoseSize * num_bones);
  cost->SetNumResiduals(residuals);
  return cost;
}

}  // namespace banmo
