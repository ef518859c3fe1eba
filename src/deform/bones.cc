#include "banmo/deform/bones.h"

#include <ceres/jet.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "banmo/util/logging.h"

namespace banmo {
namespace {

using Matrix34d = Eigen::Matrix<double, 3, 4>;

// out = R(q / |q|) v with d out / d v (the rotation matrix) and d out / d q
// (Jets over the four quaternion coordinates only).
void RotateWithJacobian(const double* q, const Eigen::Vector3d& v, Eigen::Vector3d* out,
                        Eigen::Matrix3d* d_v, Matrix34d* d_q) {
  using J = ceres::Jet<double, 4>;
  J qj[4], vj[3], rj[3];
  for (int k = 0; k < 4; ++k) qj[k] = J(q[k], k);
  for (int k = 0; k < 3; ++k) vj[k] = J(v[k]);
  ceres::QuaternionRotatePoint(qj, vj, rj);
  for (int r = 0; r < 3; ++r) {
    (*out)[r] = rj[r].a;
    d_q->row(r) = rj[r].v.transpose();
  }
  double rotation[9];
  ceres::QuaternionToRotation(q, rotation);  // row-major, q normalised
  *d_v = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(rotation);
}

// As RotateWithJacobian for the conjugate rotation R(q)^T v, with d out / d q
// with respect to q itself.
void InverseRotateWithJacobian(const double* q, const Eigen::Vector3d& v, Eigen::Vector3d* out,
                               Eigen::Matrix3d* d_v, Matrix34d* d_q) {
  const double conj[4] = {q[0], -q[1], -q[2], -q[3]};
  RotateWithJacobian(conj, v, out, d_v, d_q);
  d_q->rightCols<3>() *= -1.0;
}

// Columns of a bone term's local Jacobians: [x (3), rest bone (kBoneSize),
// bone transform (kPoseSize)].
constexpr int kLocalX = 0;
constexpr int kLocalBone = 3;
constexpr int kLocalPose = 3 + kBoneSize;
constexpr int kLocalDim = 3 + kBoneSize + kPoseSize;
using LocalRow = Eigen::Matrix<double, 1, kLocalDim>;
using LocalMatrix = Eigen::Matrix<double, 3, kLocalDim>;

// d l_b(y) with respect to y and the rest bone's columns, l_b as BoneLogit:
// d = R_b^T (y - c), l = -1/2 sum_k d_k^2 exp(-2 s_k).
void BoneLogitJacobian(const double* bone, const Eigen::Vector3d& y, Eigen::Vector3d* d_y,
                       LocalRow* d_local) {
  const Eigen::Vector3d centre(bone + kBoneCenter);
  Eigen::Vector3d d;
  Eigen::Matrix3d d_d_e;
  Matrix34d d_d_q;
  InverseRotateWithJacobian(bone + kBoneQw, y - centre, &d, &d_d_e, &d_d_q);
  Eigen::Vector3d g;  // dl / dd
  for (int k = 0; k < 3; ++k) {
    const double inv_s2 = std::exp(-2.0 * bone[kBoneLogScale + k]);
    g[k] = -d[k] * inv_s2;
    (*d_local)[kLocalBone + kBoneLogScale + k] = d[k] * d[k] * inv_s2;
  }
  *d_y = d_d_e.transpose() * g;
  d_local->segment<3>(kLocalBone + kBoneCenter) = -d_y->transpose();
  d_local->segment<4>(kLocalBone + kBoneQw) = g.transpose() * d_d_q;
}

// The hand-written Jacobian of one bone's term of the warp (BackwardBoneTerm
// or ForwardBoneTerm): d logit and d point with respect to [x, bone,
// bone_t]. Its autodiff twin is the Jet evaluation of the same templates
// (tests/deform/bones_test.cc).
void BoneTermJacobian(WarpDirection direction, const double* bone, const double* pose,
                      const double* x, LocalRow* d_logit, LocalMatrix* d_point) {
  d_logit->setZero();
  d_point->setZero();
  const Eigen::Vector3d xv(x);
  Eigen::Vector3d d_y;
  if (direction == WarpDirection::kBackward) {
    // y = R^T (x - t); logit = l_b(y); point = y.
    const Eigen::Vector3d t(pose + kPoseT);
    Eigen::Vector3d y;
    Eigen::Matrix3d y_u;
    Matrix34d y_q;
    InverseRotateWithJacobian(pose + kPoseQw, xv - t, &y, &y_u, &y_q);
    BoneLogitJacobian(bone, y, &d_y, d_logit);
    d_point->middleCols<3>(kLocalX) = y_u;
    d_point->middleCols<4>(kLocalPose + kPoseQw) = y_q;
    d_point->middleCols<3>(kLocalPose + kPoseT) = -y_u;
    d_logit->segment<kPoseSize>(kLocalPose) =
        d_y.transpose() * d_point->middleCols<kPoseSize>(kLocalPose);
    d_logit->segment<3>(kLocalX) = d_y.transpose() * y_u;
  } else {
    // logit = l_b(x); point = R x + t.
    BoneLogitJacobian(bone, xv, &d_y, d_logit);
    d_logit->segment<3>(kLocalX) = d_y.transpose();
    Eigen::Vector3d z;
    Eigen::Matrix3d z_x;
    Matrix34d z_q;
    RotateWithJacobian(pose + kPoseQw, xv, &z, &z_x, &z_q);
    d_point->middleCols<3>(kLocalX) = z_x;
    d_point->middleCols<4>(kLocalPose + kPoseQw) = z_q;
    d_point->middleCols<3>(kLocalPose + kPoseT).setIdentity();
  }
}

}  // namespace

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
  for (int b = 0; b < num_bones; ++b) {
    if (w[b] < cutoff) continue;
    LocalRow logit;
    LocalMatrix p;
    BoneTermJacobian(direction, bones + kBoneSize * b, bones_t + kPoseSize * b, x, &logit, &p);
    // d out / d (locals of bone b) = w_b (p_b - out) dl_b + w_b dp_b.
    const Eigen::Vector3d lever = points.col(b) - blended;
    const LocalMatrix d_local = w[b] * (lever * logit + p);
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
