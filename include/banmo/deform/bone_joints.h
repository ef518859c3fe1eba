// Joints between neighbouring rest bones, for the bone-joint regulariser
// (losses/regularizers.h, MakeBoneJointCostFunction; docs/solver.md, "Bone
// joints").
//
// BANMo's bones are free Gaussians with no skeleton: each frame's bone
// transforms J_b^t are independent SE(3)s. A limb can then follow the data by
// sliding its bones instead of turning them about the joint it hangs from.
// A joint ties two neighbouring bones at one canonical point m: both
// transforms should move m to the same place, J_a^t m = J_b^t m, which
// leaves them free to turn about m relative to each other (a ball joint).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace banmo {

struct BoneJoint {
  int a = 0;  // bone indices, a < b
  int b = 0;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // canonical joint point m
};

// The joints of B rest bones (kBoneSize B doubles, deform/bones.h): the
// edges of the minimum spanning tree of the bones (Prim, deterministic), with
// the distance of two bones measured in their Gaussians' widths along the
// line between them: |c_b - c_a| / (s_a + s_b), s_x = (d^T Q_x d)^(-1/2) for
// the unit direction d. Each edge's joint point lies on the segment c_a c_b,
// where the two Gaussians' logits are equal: c_a + s_a / (s_a + s_b)
// (c_b - c_a). B - 1 joints (none for B < 2); sorted by (a, b).
std::vector<BoneJoint> FindBoneJoints(const double* bones, int num_bones);

}  // namespace banmo
