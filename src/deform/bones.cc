#include "banmo/deform/bones.h"

#include <ceres/jet.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "banmo/util/logging.h"

namespace banmo {

void SkinningWeights(int num_bones, const double* logits, double* weights) {
  const double max_logit = *std::max_element(logits, logits + num_bones);
  double denom = 0.0;
  for (int b = 0; b < num_bones; ++b) {
    weights[b] = std::exp(logits[b] - max_logit);
    denom += weights[b];
  }
  for (int b = 0; b < num_bones; ++b) weights[b] /= denom;
}

Eigen::Vector4d MeanBoneRotation(int num_bones, const double* bones_t, const double* weights) {
  CHECK_GT(num_bones, 0);
  auto weight = [&](int b) { return weights != nullptr ? weights[b] : 1.0; };
  int heaviest = 0;
  for (int b = 1; b < num_bones; ++b) {
    if (weight(b) > weight(heaviest)) heaviest = b;
  }
  CHECK_GT(weight(heaviest), 0.0);
  const Eigen::Map<const Eigen::Vector4d> q_ref(bones_t + kPoseSize * heaviest + kPoseQw);
  Eigen::Vector4d q = Eigen::Vector4d::Zero();
  for (int b = 0; b < num_bones; ++b) {
    Eigen::Vector4d qb(bones_t + kPoseSize * b + kPoseQw);
    qb.normalize();
    q += (qb.dot(q_ref) < 0.0 ? -weight(b) : weight(b)) * qb;
  }
  // Every term points into the heaviest bone's hemisphere, so
  // |q| >= q . q_ref / |q_ref| >= w_max > 0: the normalisation is safe.
  return q.normalized();
}

void TransferBoneMotion(int old_num_bones, const double* old_bones, const double* old_bones_t,
                        int new_num_bones, const double* new_bones, double* new_bones_t) {
  std::vector<double> logits(old_num_bones), w(old_num_bones);
  for (int k = 0; k < new_num_bones; ++k) {
    double* out = new_bones_t + kPoseSize * k;
    PoseSetIdentity(out);
    if (old_num_bones == 0) continue;
    const double* c = new_bones + kBoneSize * k + kBoneCenter;
    for (int b = 0; b < old_num_bones; ++b) logits[b] = BoneLogit(old_bones + kBoneSize * b, c);
    SkinningWeights(old_num_bones, logits.data(), w.data());
    const Eigen::Vector4d q = MeanBoneRotation(old_num_bones, old_bones_t, w.data());
    std::copy(q.data(), q.data() + 4, out + kPoseQw);
    double warped[3], rotated[3];
    ForwardWarp(old_num_bones, old_bones, old_bones_t, c, warped);
    PoseRotateVector(out, c, rotated);
    for (int i = 0; i < 3; ++i) out[kPoseT + i] = warped[i] - rotated[i];
  }
}

void WarpWithJacobian(WarpDirection direction, int num_bones, const double* bones,
                      const double* bones_t, const double* x, double* out, WarpJacobian* jacobian,
                      const double* delta_logits, double jacobian_cutoff) {
  jacobian->d_x.setZero();
  jacobian->d_bones.setZero(3, kBoneSize * num_bones);
  jacobian->d_bones_t.setZero(3, kPoseSize * num_bones);
  jacobian->d_delta_logits.setZero(3, delta_logits != nullptr ? num_bones : 0);
  if (num_bones == 0) {
    std::copy(x, x + 3, out);
    jacobian->d_x.setIdentity();
    return;
  }
  // Values first (doubles): logits, points and weights of every bone.
  std::vector<double> logits(num_bones), w(num_bones);
  Eigen::Matrix<double, 3, Eigen::Dynamic> points(3, num_bones);
  for (int b = 0; b < num_bones; ++b) {
    const double* bone = bones + kBoneSize * b;
    const double* pose = bones_t + kPoseSize * b;
    if (direction == WarpDirection::kBackward) {
      BackwardBoneTerm(bone, pose, x, &logits[b], points.col(b).data());
    } else {
      ForwardBoneTerm(bone, pose, x, &logits[b], points.col(b).data());
    }
    if (delta_logits != nullptr) logits[b] += delta_logits[b];
  }
  SkinningWeights(num_bones, logits.data(), w.data());
  const Eigen::Vector3d blended = points * Eigen::Map<const Eigen::VectorXd>(w.data(), num_bones);
  std::copy(blended.data(), blended.data() + 3, out);

  // Derivatives: every term of bone b is scaled by its weight w_b; bones
  // below the cutoff are skipped (their Jacobian columns stay zero).
  const double cutoff = std::max(jacobian_cutoff, kNegligibleSkinningWeight);
  constexpr int kDim = 3 + kBoneSize + kPoseSize;  // Jets over [x, bone, bone_t]
  using J = ceres::Jet<double, kDim>;
  J xj[3];
  for (int k = 0; k < 3; ++k) xj[k] = J(x[k], k);
  for (int b = 0; b < num_bones; ++b) {
    if (w[b] < cutoff) continue;
    J bone[kBoneSize], pose[kPoseSize];
    for (int k = 0; k < kBoneSize; ++k) bone[k] = J(bones[kBoneSize * b + k], 3 + k);
    for (int k = 0; k < kPoseSize; ++k) {
      pose[k] = J(bones_t[kPoseSize * b + k], 3 + kBoneSize + k);
    }
    J logit, p[3];
    if (direction == WarpDirection::kBackward) {
      BackwardBoneTerm(bone, pose, xj, &logit, p);
    } else {
      ForwardBoneTerm(bone, pose, xj, &logit, p);
    }
    // d out / d (locals of bone b) = w_b (p_b - out) dl_b + w_b dp_b.
    Eigen::Matrix<double, 3, kDim> d_local;
    const Eigen::Vector3d lever = points.col(b) - blended;
    for (int r = 0; r < 3; ++r) d_local.row(r) = w[b] * (lever[r] * logit.v + p[r].v).transpose();
    jacobian->d_x += d_local.leftCols<3>();
    jacobian->d_bones.middleCols<kBoneSize>(kBoneSize * b) = d_local.middleCols<kBoneSize>(3);
    jacobian->d_bones_t.middleCols<kPoseSize>(kPoseSize * b) = d_local.rightCols<kPoseSize>();
    if (delta_logits != nullptr) jacobian->d_delta_logits.col(b) = w[b] * lever;
  }
}

void InitializeBones(const std::vector<Eigen::Vector3d>& centres, double scale, double* bones) {
  CHECK_GT(scale, 0.0);
  for (size_t b = 0; b < centres.size(); ++b) {
    double* bone = bones + kBoneSize * b;
    for (int k = 0; k < 3; ++k) bone[kBoneCenter + k] = centres[b][k];
    bone[kBoneQw] = 1.0;
    bone[kBoneQw + 1] = bone[kBoneQw + 2] = bone[kBoneQw + 3] = 0.0;
    for (int k = 0; k < 3; ++k) bone[kBoneLogScale + k] = std::log(scale);
  }
}

}  // namespace banmo
