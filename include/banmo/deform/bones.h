// Gaussian bones and linear blend skinning (BANMo, Yang et al. CVPR 2022,
// Sec. 3.2, Eqs. 8-10, 13-14), templated for Jets.
//
// Rest bone block (kBoneSize = 10 doubles, canonical coordinates):
//   [cx, cy, cz, qw, qx, qy, qz, log_sx, log_sy, log_sz]
// centre C_b, orientation V_b (unit quaternion, normalised on use) and log
// scales of the Gaussian. The precision matrix is
//   Q_b = V_b diag(exp(-2 log_s)) V_b^T,
// and the skinning logit of a point y in rest coordinates is
//   l_b(y) = -1/2 (y - C_b)^T Q_b (y - C_b)                     (Eq. 13)
// (the paper's W_sigma with the Gaussian's sign and factor made explicit).
// Skinning weights are softmax_b(l_b + d_b) (Eq. 14), where d = W_Delta are
// optional delta-skinning logits (delta_skinning.h; null = zero) evaluated
// by the caller at the warp's input point.
//
// Bone transform block at frame t (kPoseSize = 7, geometry/se3.h):
//   posed_from_rest J_b^t: moves bone b from its rest configuration to time t
//   (both in the object's root frame).
//
// Backward warp (Eq. 9-10): x_in_root at time t -> canonical point
//   y_b = (J_b^t)^{-1} x,  l_b = l_b(y_b)  (the Gaussian moved by J_b^t,
//   evaluated at x, equals the rest Gaussian at y_b),
//   X* = sum_b softmax(l)_b y_b.
// Forward warp (Eq. 8, 10): canonical X* -> root frame at time t
//   l_b = l_b(X*) (rest bones),  z_b = J_b^t X*,  x = sum_b softmax(l)_b z_b.
// With B = 0 bones both warps are the identity (a rigid object).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <vector>

#include "banmo/geometry/se3.h"

namespace banmo {

inline constexpr int kBoneSize = 10;
inline constexpr int kBoneCenter = 0;
inline constexpr int kBoneQw = 3;
inline constexpr int kBoneLogScale = 7;

// l_b(y) for a rest bone and a point in rest (canonical) coordinates.
template <typename T>
inline T BoneLogit(const T* bone, const T* y) {
  const T d_world[3] = {y[0] - bone[kBoneCenter + 0], y[1] - bone[kBoneCenter + 1],
                        y[2] - bone[kBoneCenter + 2]};
  const T conj[4] = {bone[kBoneQw], -bone[kBoneQw + 1], -bone[kBoneQw + 2], -bone[kBoneQw + 3]};
  T d_bone[3];
  ceres::QuaternionRotatePoint(conj, d_world, d_bone);
  T sum(0);
  for (int k = 0; k < 3; ++k) {
    sum += d_bone[k] * d_bone[k] * exp(T(-2.0) * bone[kBoneLogScale + k]);
  }
  return T(-0.5) * sum;
}

// Per-bone term of the backward warp: y = (J_b^t)^{-1} x, logit = l_b(y).
template <typename T>
inline void BackwardBoneTerm(const T* bone, const T* posed_from_rest, const T* x_in_root, T* logit,
                             T* y) {
  PoseInverseTransformPoint(posed_from_rest, x_in_root, y);
  *logit = BoneLogit(bone, y);
}

// Per-bone term of the forward warp: logit = l_b(X*), z = J_b^t X*.
template <typename T>
inline void ForwardBoneTerm(const T* bone, const T* posed_from_rest, const T* x_canonical, T* logit,
                            T* z) {
  *logit = BoneLogit(bone, x_canonical);
  PoseTransformPoint(posed_from_rest, x_canonical, z);
}

// out = sum_b softmax(logits)_b * points_b, with the softmax computed as
// exp(l_b - max l) / sum exp(l - max l) so logits of any magnitude (1e4, or
// -1e8 for tiny bones) stay finite. points is 3 x B, column-major.
template <typename T>
inline void BlendPoints(int num_bones, const T* logits, const T* points, T* out) {
  T max_logit = logits[0];
  for (int b = 1; b < num_bones; ++b) {
    if (logits[b] > max_logit) max_logit = logits[b];
  }
  T denom(0);
  out[0] = out[1] = out[2] = T(0);
  for (int b = 0; b < num_bones; ++b) {
    const T e = exp(logits[b] - max_logit);
    denom += e;
    out[0] += e * points[3 * b + 0];
    out[1] += e * points[3 * b + 1];
    out[2] += e * points[3 * b + 2];
  }
  out[0] /= denom;
  out[1] /= denom;
  out[2] /= denom;
}

// Softmax weights (log-sum-exp safe), for inspection and export.
void SkinningWeights(int num_bones, const double* logits, double* weights);

// Backward warp x_in_root (time t) -> canonical. bones: B rest blocks
// (kBoneSize each, contiguous); bones_t: B transforms (kPoseSize each);
// delta_logits: B delta-skinning logits at x_in_root (null = none).
template <typename T>
void BackwardWarp(int num_bones, const T* bones, const T* bones_t, const T* x_in_root,
                  T* x_canonical, const T* delta_logits = nullptr) {
  if (num_bones == 0) {
    std::copy(x_in_root, x_in_root + 3, x_canonical);
    return;
  }
  std::vector<T> logits(num_bones), points(3 * num_bones);
  for (int b = 0; b < num_bones; ++b) {
    BackwardBoneTerm(bones + kBoneSize * b, bones_t + kPoseSize * b, x_in_root, &logits[b],
                     &points[3 * b]);
    if (delta_logits != nullptr) logits[b] += delta_logits[b];
  }
  BlendPoints(num_bones, logits.data(), points.data(), x_canonical);
}

// Forward warp canonical -> x_in_root at time t (delta_logits: at
// x_canonical, null = none).
template <typename T>
void ForwardWarp(int num_bones, const T* bones, const T* bones_t, const T* x_canonical,
                 T* x_in_root, const T* delta_logits = nullptr) {
  if (num_bones == 0) {
    std::copy(x_canonical, x_canonical + 3, x_in_root);
    return;
  }
  std::vector<T> logits(num_bones), points(3 * num_bones);
  for (int b = 0; b < num_bones; ++b) {
    ForwardBoneTerm(bones + kBoneSize * b, bones_t + kPoseSize * b, x_canonical, &logits[b],
                    &points[3 * b]);
    if (delta_logits != nullptr) logits[b] += delta_logits[b];
  }
  BlendPoints(num_bones, logits.data(), points.data(), x_in_root);
}

// A warp's output and its exact first derivatives (mixed mode): per-bone
// terms are differentiated with Jets over (x, bone, bone_t) only (20
// directions), and the blend is differentiated by hand:
//   d out / d l_b = w_b (p_b - out),   d out / d p_b = w_b I.
// d_x is the partial derivative with the delta logits held fixed; the caller
// chains d_delta_logits through the delta-skinning MLP.
struct WarpJacobian {
  Eigen::Matrix3d d_x = Eigen::Matrix3d::Zero();            // d out / d x
  Eigen::Matrix<double, 3, Eigen::Dynamic> d_bones;         // 3 x (kBoneSize B)
  Eigen::Matrix<double, 3, Eigen::Dynamic> d_bones_t;       // 3 x (kPoseSize B)
  Eigen::Matrix<double, 3, Eigen::Dynamic> d_delta_logits;  // 3 x B (with delta logits)
};

enum class WarpDirection { kBackward, kForward };

// Skinning weights below this contribute less than double rounding to a
// warp's derivatives (every term of a bone is scaled by its weight): the
// smallest cutoff WarpWithJacobian applies.
inline constexpr double kNegligibleSkinningWeight = 1e-16;

// Evaluates the warp (as BackwardWarp / ForwardWarp) and its Jacobian.
// Bones whose skinning weight at x is below max(jacobian_cutoff,
// kNegligibleSkinningWeight) are left out of the derivatives (their columns
// stay zero; the value still blends every bone). Every derivative term of
// bone b is w_b ((p_b - out) dl_b + dp_b): the derivatives with respect to
// the kept bones' blocks stay exact, and each left-out bone changes an entry
// of d out / d x by w_b (|p_b - out| |dl_b/dx| + |dp_b/dx|) at most, less
// than the cutoff times that bone's (bounded) derivative terms.
void WarpWithJacobian(WarpDirection direction, int num_bones, const double* bones,
                      const double* bones_t, const double* x, double* out, WarpJacobian* jacobian,
                      const double* delta_logits = nullptr, double jacobian_cutoff = 0.0);

// The weighted mean rotation of a frame's bone transforms, as a unit
// quaternion [w, x, y, z]: the quaternions turned into the hemisphere of the
// heaviest bone's, summed with their weights, normalised (weights: B
// non-negative numbers, not all zero; null = equal). Turning every bone by
// one rotation M turns the mean by M exactly (the sum is linear in the
// quaternions), so the root composed with it does not see the gauge
// freedom of a frame (turn all bones by M, the root by M^-1).
Eigen::Vector4d MeanBoneRotation(int num_bones, const double* bones_t,
                                 const double* weights = nullptr);

// Bone transforms of a frame for new rest bones that carry the motion the
// old bones gave that frame (a bone re-initialisation that keeps the
// articulation learnt so far). New bone k, centred at c_k, gets
//   R'_k: the old skinning weights at c_k averaging the old rotations
//         (quaternions turned into the hemisphere of the heaviest bone's,
//         then normalised; exact when the old rotations agree),
//   t'_k: c_k lands where the old forward warp takes it,
//         J'_k c_k = ForwardWarp_old(c_k)  (Eq. 8, 10),
// so a frame whose old bones all moved by one rigid motion M gives every
// new bone M. Old delta logits are not used (the re-initialisation resets
// them). With no old bones every new transform is the identity.
void TransferBoneMotion(int old_num_bones, const double* old_bones, const double* old_bones_t,
                        int new_num_bones, const double* new_bones, double* new_bones_t);

// Initialises B rest bones: centres at the given points, identity
// orientation, isotropic scale `scale` (log-scale log(scale)).
void InitializeBones(const std::vector<Eigen::Vector3d>& centres, double scale, double* bones);

}  // namespace banmo
