// The solver's state beyond the model's parameters: everything a resumed
// run needs to continue bit-identically (checkpoint state.bin).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "banmo/model/parameter_group.h"
#include "banmo/optim/ray_sampler.h"

namespace banmo {

struct SolverState {
  int stage = 0;
  int batch = 0;  // batches done in the stage
  int total_batches = 0;
  std::mt19937 rng;
  double lm_radius = -1.0;  // < 0: the stage's initial radius
  struct Moments {
    std::vector<double> m, v;
    int64_t steps = 0;
  };
  // By block name (Model::ForEachBlock), and by BasisMomentsName for the
  // temporal step bases.
  std::map<std::string, Moments> adam;
  std::vector<RaySampler::CachedPixel> error_cache;
  Eigen::AlignedBox3d bounds;

  // Forgets the Adam moments of every block of these groups and of their
  // temporal bases (blocks whose parameters jumped: a solve or a
  // registration moved them, or their tangent space changed).
  void DropAdamMoments(ParameterGroupSet groups);
  // Forgets the moments of every temporal basis (the bones changed).
  void DropAdamBasisMoments();

  // state.bin: "BANMOST1", then the fields above in order.
  std::string Serialize() const;
  // Throws InputError on a truncated or foreign file.
  void Deserialize(const std::string& in);
};

// The Adam moments' name of video v's temporal step basis of `group`
// (kBonesT or kRoot; AdamConfig::bone_basis / root_basis), e.g.
// "video3/bones_t_basis": its frames' block name with "_basis".
std::string BasisMomentsName(int video, ParameterGroup group);

// The group of an entry of SolverState::adam: its block's
// (Model::BlockGroup) or its basis's; none for another name.
std::optional<ParameterGroup> AdamMomentsGroup(const std::string& name);

}  // namespace banmo
