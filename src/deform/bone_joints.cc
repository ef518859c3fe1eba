#include "banmo/deform/bone_joints.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "banmo/deform/bones.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

// The Gaussian's width along the unit direction d: (d^T Q d)^(-1/2), with
// Q = V diag(exp(-2 log s)) V^T (deform/bones.h).
double WidthAlong(const double* bone, const Eigen::Vector3d& d) {
  Eigen::Quaterniond v(bone[kBoneQw], bone[kBoneQw + 1], bone[kBoneQw + 2], bone[kBoneQw + 3]);
  v.normalize();
  const Eigen::Vector3d local = v.conjugate() * d;
  double q = 0.0;
  for (int k = 0; k < 3; ++k) q += local[k] * local[k] * std::exp(-2.0 * bone[kBoneLogScale + k]);
  return 1.0 / std::sqrt(q);
}

}  // namespace

std::vector<BoneJoint> FindBoneJoints(const double* bones, int num_bones) {
  CHECK_GE(num_bones, 0);
  std::vector<BoneJoint> joints;
  if (num_bones < 2) return joints;
  auto centre = [&](int b) { return Eigen::Map<const Eigen::Vector3d>(bones + kBoneSize * b); };
  // The widths of bones a and b along the line between them (1 and 1 for
  // coincident centres: distance 0, joint at the midpoint).
  auto widths = [&](int a, int b) {
    const Eigen::Vector3d ab = centre(b) - centre(a);
    const double length = ab.norm();
    if (length == 0.0) return Eigen::Vector2d(1.0, 1.0);
    const Eigen::Vector3d d = ab / length;
    return Eigen::Vector2d(WidthAlong(bones + kBoneSize * a, d),
                           WidthAlong(bones + kBoneSize * b, d));
  };
  Eigen::MatrixXd dist = Eigen::MatrixXd::Zero(num_bones, num_bones);
  for (int a = 0; a < num_bones; ++a) {
    for (int b = a + 1; b < num_bones; ++b) {
      const Eigen::Vector2d s = widths(a, b);
      dist(a, b) = dist(b, a) = (centre(b) - centre(a)).norm() / (s[0] + s[1]);
    }
  }
  // Prim's algorithm from bone 0; ties go to the lower index.
  std::vector<bool> in_tree(num_bones, false);
  std::vector<double> best(num_bones, std::numeric_limits<double>::infinity());
  std::vector<int> parent(num_bones, -1);
  best[0] = 0.0;
  for (int step = 0; step < num_bones; ++step) {
    int next = -1;
    for (int b = 0; b < num_bones; ++b) {
      if (!in_tree[b] && (next < 0 || best[b] < best[next])) next = b;
    }
    in_tree[next] = true;
    if (parent[next] >= 0) {
      BoneJoint j;
      j.a = std::min(next, parent[next]);
      j.b = std::max(next, parent[next]);
      const Eigen::Vector2d s = widths(j.a, j.b);
      j.point = centre(j.a) + (s[0] / (s[0] + s[1])) * (centre(j.b) - centre(j.a));
      joints.push_back(j);
    }
    for (int b = 0; b < num_bones; ++b) {
      if (!in_tree[b] && dist(next, b) < best[b]) {
        best[b] = dist(next, b);
        parent[b] = next;
      }
    }
  }
  std::sort(joints.begin(), joints.end(), [](const BoneJoint& x, const BoneJoint& y) {
    return x.a != y.a ? x.a < y.a : x.b < y.b;
  });
  return joints;
}

}  // namespace banmo
