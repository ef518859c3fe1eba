// The parameter groups of a model (model/model.h): the unit in which stages
// hold parameters constant (config `constant:`), the solver sets learning
// rates and step rules, and retargeting freezes shared blocks. One naming for
// model, config and solver.
#pragma once

#include <initializer_list>
#include <utility>

#include "banmo/util/enum_names.h"

namespace banmo {

enum class ParameterGroup {
  kSdf = 0,        // SDF MLP weights
  kColor,          // colour MLP weights
  kEmbedding,      // canonical embedding MLP weights
  kLogBeta,        // log of VolSDF's beta
  kAppearance,     // per-video appearance codes
  kRoot,           // per-frame root corrections dG^t
  kBones,          // rest bones
  kBonesT,         // per-frame bone transforms
  kIntrinsics,     // per-video intrinsics
  kDeltaSkinning,  // MLP_Delta weights and the rest-pose code
  kPoseCode        // per-frame delta-skinning pose codes
};
inline constexpr int kNumParameterGroups = 11;

template <>
struct EnumNames<ParameterGroup> {
  static constexpr std::pair<ParameterGroup, const char*> kNames[] = {
      {ParameterGroup::kSdf, "sdf"},
      {ParameterGroup::kColor, "color"},
      {ParameterGroup::kEmbedding, "embedding"},
      {ParameterGroup::kLogBeta, "log_beta"},
      {ParameterGroup::kAppearance, "appearance"},
      {ParameterGroup::kRoot, "root"},
      {ParameterGroup::kBones, "bones"},
      {ParameterGroup::kBonesT, "bones_t"},
      {ParameterGroup::kIntrinsics, "intrinsics"},
      {ParameterGroup::kDeltaSkinning, "delta_skinning"},
      {ParameterGroup::kPoseCode, "pose_code"}};
};

// A set of groups, one bit each.
class ParameterGroupSet {
 public:
  ParameterGroupSet() = default;
  ParameterGroupSet(std::initializer_list<ParameterGroup> groups) {
    for (ParameterGroup g : groups) Insert(g);
  }
  bool Contains(ParameterGroup g) const { return (bits_ >> static_cast<int>(g)) & 1u; }
  void Insert(ParameterGroup g) { bits_ |= 1u << static_cast<int>(g); }
  void Erase(ParameterGroup g) { bits_ &= ~(1u << static_cast<int>(g)); }
  bool empty() const { return bits_ == 0; }
  bool operator==(const ParameterGroupSet& o) const { return bits_ == o.bits_; }

 private:
  unsigned bits_ = 0;
};

}  // namespace banmo
