// Regulariser cost functions (not per ray): eikonal, bones inside the
// surface, temporal smoothness of pose tracks, bone joints. Each comes with its full-Jet
// reference twin for the tests where a Jacobian is assembled by hand.
#pragma once

#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "banmo/deform/bone_joints.h"
#include "banmo/field/canonical_field.h"
#include "banmo/geometry/se3.h"

namespace banmo {

// Eikonal term (losses/eikonal_loss.h) at P canonical points (constants): P
// residuals, one parameter block (the SDF MLP weights). The SDF gradient
// comes from the batched forward pass and its weight Jacobian from
// CanonicalField::SdfGradientBackward (exact second-order reverse mode).
std::unique_ptr<ceres::CostFunction> MakeEikonalCostFunction(const CanonicalField& field,
                                                             const Eigen::Matrix3Xd& points,
                                                             double weight);
// Reference: the SDF gradient by nested Jets (Jet<Jet>) through the templated
// MLP, Jets over every weight.
std::unique_ptr<ceres::CostFunction> MakeEikonalReferenceCostFunction(
    const CanonicalField& field, const Eigen::Matrix3Xd& points, double weight);

// Bones-inside term (losses/bone_inside_loss.h) for all B rest bones: B
// residuals; parameter blocks: SDF MLP weights, rest bones (kBoneSize B).
std::unique_ptr<ceres::CostFunction> MakeBoneInsideCostFunction(const CanonicalField& field,
                                                                int num_bones, double margin,
                                                                double weight);
std::unique_ptr<ceres::CostFunction> MakeBoneInsideReferenceCostFunction(
    const CanonicalField& field, int num_bones, double margin, double weight);

// Temporal smoothness (losses/pose_smoothness_loss.h) of the root poses of
// frames t and t+1: G = dG * G0 with the G0 given as constants; parameter
// blocks: dG^t, dG^{t+1}. Autodiff.
std::unique_ptr<ceres::CostFunction> MakeRootSmoothnessCostFunction(const Pose& root_init_a,
                                                                    const Pose& root_init_b,
                                                                    double rotation_weight,
                                                                    double translation_weight);

// Temporal smoothness of all B bone transforms of frames t and t+1: 6B
// residuals; parameter blocks: bones_t of t and of t+1. Autodiff.
std::unique_ptr<ceres::CostFunction> MakeBoneSmoothnessCostFunction(int num_bones,
                                                                    double rotation_weight,
                                                                    double translation_weight);

// Bone joints of one frame (deform/bone_joints.h): for each joint (a, b, m),
//   r = sqrt(w) (J_a^t m - J_b^t m),   3 residuals,
// the two bone transforms' images of the canonical joint point m (a
// constant); parameter block: bones_t of the frame (kPoseSize B). Zero when
// the two bones move m alike, whatever they do elsewhere. Autodiff.
std::unique_ptr<ceres::CostFunction> MakeBoneJointCostFunction(int num_bones,
                                                               std::vector<BoneJoint> joints,
                                                               double weight);

}  // namespace banmo
