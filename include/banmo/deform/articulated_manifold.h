// Articulated steps of a frame's bone transforms: the bones as a kinematic
// tree (the joints of FindBoneJoints, deform/bone_joints.h), each bone turning
// about its joint with its parent and carrying its descendants with it
// (docs/solver.md, "Articulated bone steps").
//
// BANMo's bone transforms J_b^t are B free SE(3)s (6 B unknowns a frame). A
// limb can then follow the data by sliding its bones; the `bone_joint` loss
// term narrows the joints' gaps but cannot close them. This manifold takes
// the sliding away from the step instead: the tangent space of a frame's
// 7 B doubles is the root bone's rigid step (6: a turn about its centre and
// a translation) and one turn per other bone about its joint (3 each), 3 B + 3
// in all. Every step moves whole subtrees rigidly, so it keeps each joint's
// gap |J_a m - J_b m| as it is: bones that start at the identity (zero gaps)
// stay joined as long as the joints do not move.
#pragma once

#include <ceres/manifold.h>

#include <Eigen/Core>
#include <memory>
#include <vector>

namespace banmo {

// FindBoneJoints' spanning tree of the rest bones, rooted at its centre (the
// bone with the fewest edges to the farthest bone; ties to the lower index).
struct BoneTree {
  int root = -1;                       // -1 for no bones
  std::vector<int> order;              // every bone, each after its parent
  std::vector<int> parent;             // per bone; -1 for the root
  std::vector<Eigen::Vector3d> pivot;  // per bone, canonical: the joint with
                                       // its parent (the root: its centre)
  std::vector<int> tangent_offset;     // per bone: root 0 (6 wide), others 3 wide
  int TangentSize() const { return order.empty() ? 0 : 3 * static_cast<int>(order.size()) + 3; }
};

// The tree of B rest bones (kBoneSize B doubles, deform/bones.h). The root's
// tangent block comes first, then the other bones' in bone order.
BoneTree MakeBoneTree(const double* bones, int num_bones);

// The manifold of one frame's bone transforms (kPoseSize B doubles, pose b at
// 7 b) under `tree`, which is read at every call: the caller may rebuild it
// between steps (e.g. once a batch, from the rest bones as they move) but not
// change its number of bones. Ambient 7 B, tangent 3 B + 3.
//
// Plus, bone by bone from the root down, with each bone's step a rigid motion
// D_b of the posed space (w, v: the bone's tangent block):
//   root r:   D_r p = E(w_r) (p - P_r) + P_r + v,   P_r = J_r C_r (its posed centre)
//   bone b:   D_b p = E(w_b) (D_a p - P_b) + P_b,   P_b = D_a J_b m_b
// for parent a and joint point m_b, and J_b' = D_b J_b. E(w) is the rotation
// of ceres::QuaternionManifold's step (quaternion [cos|w|, sin|w| w/|w|]).
// A bone's turn keeps its own joint point in place and carries its subtree.
// PlusJacobian is exact (Jets, one tangent direction at a time). Minus and
// MinusJacobian are first-order (the least-squares tangent of y - x through
// the pseudo-inverse of PlusJacobian): nothing in banmo calls them, and y
// need not be reachable from x.
std::unique_ptr<ceres::Manifold> MakeArticulatedBoneManifold(int num_bones, const BoneTree* tree);

}  // namespace banmo
