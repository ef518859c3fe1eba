#include "banmo/deform/articulated_manifold.h"

#include <ceres/jet.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>
#include <algorithm>
#include <deque>
#include <limits>

#include "banmo/deform/bone_joints.h"
#include "banmo/deform/bones.h"
#include "banmo/geometry/pose_manifold.h"
#include "banmo/geometry/se3.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Breadth-first distances (edges) from `from` in the tree `neighbours`.
std::vector<int> HopsFrom(const std::vector<std::vector<int>>& neighbours, int from) {
  std::vector<int> hops(neighbours.size(), -1);
  std::deque<int> queue{from};
  hops[from] = 0;
  while (!queue.empty()) {
    const int a = queue.front();
    queue.pop_front();
    for (int b : neighbours[a]) {
      if (hops[b] < 0) {
        hops[b] = hops[a] + 1;
        queue.push_back(b);
      }
    }
  }
  return hops;
}

// The Plus of the header, on any scalar (Jets for the Jacobian).
template <typename T>
void ArticulatedPlus(const BoneTree& tree, const double* x, const T* delta, T* y) {
  const int B = static_cast<int>(tree.order.size());
  // D_b as a pose [q, t]: p -> R(q) p + t.
  std::vector<T> steps(static_cast<size_t>(kPoseSize) * B);
  for (int b : tree.order) {
    const double* pose = x + kPoseSize * b;
    const T* w = delta + tree.tangent_offset[b];
    T d_parent[kPoseSize];
    if (tree.parent[b] < 0) {
      PoseSetIdentity(d_parent);
    } else {
      std::copy_n(steps.data() + kPoseSize * tree.parent[b], kPoseSize, d_parent);
    }
    // P_b = D_a J_b m_b.
    double jm[3];
    PoseTransformPoint(pose, tree.pivot[b].data(), jm);
    const T jm_t[3] = {T(jm[0]), T(jm[1]), T(jm[2])};
    T pivot[3];
    PoseTransformPoint(d_parent, jm_t, pivot);
    // D_b = E(w) (D_a - P_b) + P_b (+ v for the root).
    T e[4];
    StepQuaternion(w, e);
    T* d = steps.data() + kPoseSize * b;
    ceres::QuaternionProduct(e, d_parent + kPoseQw, d + kPoseQw);
    const T shifted[3] = {d_parent[kPoseT] - pivot[0], d_parent[kPoseT + 1] - pivot[1],
                          d_parent[kPoseT + 2] - pivot[2]};
    T turned[3];
    ceres::QuaternionRotatePoint(e, shifted, turned);
    for (int k = 0; k < 3; ++k) d[kPoseT + k] = turned[k] + pivot[k];
    if (tree.parent[b] < 0) {
      for (int k = 0; k < 3; ++k) d[kPoseT + k] += w[3 + k];
    }
    // J_b' = D_b J_b.
    T j[kPoseSize];
    for (int k = 0; k < kPoseSize; ++k) j[k] = T(pose[k]);
    PoseCompose(d, j, y + kPoseSize * b);
  }
}

class ArticulatedBoneManifold final : public ceres::Manifold {
 public:
  ArticulatedBoneManifold(int num_bones, const BoneTree* tree)
      : num_bones_(num_bones), tree_(tree) {
    CHECK_GT(num_bones, 0);
    CHECK(tree != nullptr);
    CHECK_EQ(static_cast<int>(tree->order.size()), num_bones);
  }
  int AmbientSize() const override { return kPoseSize * num_bones_; }
  int TangentSize() const override { return 3 * num_bones_ + 3; }

  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    CheckTree();
    ArticulatedPlus(*tree_, x, delta, x_plus_delta);
    return true;
  }

  bool PlusJacobian(const double* x, double* jacobian) const override {
    CheckTree();
    const int n = AmbientSize(), m = TangentSize();
    Eigen::Map<RowMajorMatrix> jac(jacobian, n, m);
    using Jet = ceres::Jet<double, 1>;
    std::vector<Jet> delta(m, Jet(0.0)), y(n);
    for (int c = 0; c < m; ++c) {
      delta[c].v[0] = 1.0;
      ArticulatedPlus(*tree_, x, delta.data(), y.data());
      for (int r = 0; r < n; ++r) jac(r, c) = y[r].v[0];
      delta[c].v[0] = 0.0;
    }
    return true;
  }

  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    const RowMajorMatrix pinv = PseudoInverse(x);
    Eigen::Map<const Eigen::VectorXd> yv(y, AmbientSize()), xv(x, AmbientSize());
    Eigen::Map<Eigen::VectorXd>(y_minus_x, TangentSize()) = pinv * (yv - xv);
    return true;
  }

  bool MinusJacobian(const double* x, double* jacobian) const override {
    Eigen::Map<RowMajorMatrix>(jacobian, TangentSize(), AmbientSize()) = PseudoInverse(x);
    return true;
  }

 private:
  void CheckTree() const {
    CHECK_EQ(static_cast<int>(tree_->order.size()), num_bones_)
        << "the bone tree changed its number of bones";
  }
  RowMajorMatrix PseudoInverse(const double* x) const {
    RowMajorMatrix plus(AmbientSize(), TangentSize());
    CHECK(PlusJacobian(x, plus.data()));
    return plus.completeOrthogonalDecomposition().pseudoInverse();
  }

  const int num_bones_;
  const BoneTree* tree_;
};

}  // namespace

BoneTree MakeBoneTree(const double* bones, int num_bones) {
  CHECK_GE(num_bones, 0);
  BoneTree tree;
  if (num_bones == 0) return tree;
  const std::vector<BoneJoint> joints = FindBoneJoints(bones, num_bones);
  std::vector<std::vector<int>> neighbours(num_bones);
  for (const BoneJoint& j : joints) {
    neighbours[j.a].push_back(j.b);
    neighbours[j.b].push_back(j.a);
  }
  for (auto& n : neighbours) std::sort(n.begin(), n.end());
  // The centre: the least eccentric bone.
  int best = std::numeric_limits<int>::max();
  for (int b = 0; b < num_bones; ++b) {
    const std::vector<int> hops = HopsFrom(neighbours, b);
    const int eccentricity = *std::max_element(hops.begin(), hops.end());
    if (eccentricity < best) {
      best = eccentricity;
      tree.root = b;
    }
  }
  tree.parent.assign(num_bones, -1);
  tree.pivot.resize(num_bones);
  tree.order = {tree.root};
  tree.pivot[tree.root] = Eigen::Map<const Eigen::Vector3d>(bones + kBoneSize * tree.root);
  for (size_t i = 0; i < tree.order.size(); ++i) {
    const int a = tree.order[i];
    for (int b : neighbours[a]) {
      if (b == tree.root || tree.parent[b] >= 0) continue;
      tree.parent[b] = a;
      tree.order.push_back(b);
    }
  }
  CHECK_EQ(static_cast<int>(tree.order.size()), num_bones) << "the bone joints are not a tree";
  for (const BoneJoint& j : joints) {
    const int child = tree.parent[j.b] == j.a ? j.b : j.a;
    tree.pivot[child] = j.point;
  }
  tree.tangent_offset.assign(num_bones, 0);
  int offset = 6;
  for (int b = 0; b < num_bones; ++b) {
    if (b == tree.root) continue;
    tree.tangent_offset[b] = offset;
    offset += 3;
  }
  return tree;
}

std::unique_ptr<ceres::Manifold> MakeArticulatedBoneManifold(int num_bones, const BoneTree* tree) {
  return std::make_unique<ArticulatedBoneManifold>(num_bones, tree);
}

}  // namespace banmo
