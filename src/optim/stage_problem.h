// The ceres::Problem of one stage (docs/solver.md): the model's parameter
// blocks with their manifolds, grouped by ParameterGroup and held constant
// as the stage says; the minibatch's residual blocks (one per active loss
// term of each ray, plus the regularisers), replaced every batch; and the
// RayBatch that evaluates them (its evaluation callback).
#pragma once

#include <ceres/loss_function.h>
#include <ceres/problem.h>

#include <Eigen/Geometry>
#include <array>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <vector>

#include "banmo/losses/ray_batch.h"
#include "banmo/model/model.h"
#include "banmo/model/parameter_group.h"
#include "banmo/optim/config.h"

namespace banmo {

struct BoneTree;

class StageProblem {
 public:
  // `extra_constant`: groups held constant on top of the stage's own.
  StageProblem(Model* model, const StageConfig& stage, const ParameterGroupSet& extra_constant);
  ~StageProblem();

  ceres::Problem& problem() { return *problem_; }
  Model& model() { return model_; }
  RayBatch& batch() { return batch_; }
  const RayRobustLosses& ray_robust() const { return ray_robust_; }
  // Residual blocks of the minibatch that are not ray terms.
  const std::vector<ceres::ResidualBlockId>& regularizer_blocks() const {
    return regularizer_blocks_;
  }

  // Adds every block of the model with its manifold and constancy (again
  // after a grow step of automatic sizing, which moves blocks).
  void AddModelBlocks();
  // Drops every residual and parameter block (before the model grows).
  void RemoveAllBlocks();
  // The groups a stage frees part-way, at batch `batch_index` of the stage:
  // - the root corrections (schedule.root_free_from) are held constant
  //   before their fraction;
  // - delta skinning (schedule.delta_skinning_from): before the fraction its
  //   groups are held constant, and while MLP_Delta's output is still zero
  //   the batch leaves it out (same values, no cost);
  // - shape, appearance and root poses are held constant for
  //   schedule.freeze_after_reinit of the stage after each bone
  //   re-initialisation.
  void ScheduleGroups(int batch_index);

  // Removes the previous minibatch's residual blocks.
  void ClearMinibatch();
  // The minibatch's residual blocks: each active term of each ray, the
  // eikonal term at points drawn from `rng` in `bounds`, bones inside the
  // surface, pose smoothness of the rays' frames and their successors.
  void SetMinibatch(std::vector<Ray> rays, const Eigen::Matrix3Xd& match_grid,
                    const Eigen::AlignedBox3d& bounds, std::mt19937* rng);

  // The non-constant blocks the minibatch reads, of the groups in `only`
  // (every group when empty), in group order.
  std::vector<double*> FreeBlocks(const ParameterGroupSet& only) const;
  // Holds the non-constant blocks of `groups` constant until Restore().
  void Hold(const ParameterGroupSet& groups);
  // Every group back to the stage's constancy.
  void Restore();

  ParameterGroup GroupOf(const double* block) const { return group_of_.at(block); }
  // Whether the stage (or the run's extra groups) holds group g constant
  // throughout; schedules' temporary holds do not count.
  bool ConfiguredConstant(ParameterGroup g) const { return configured_constant_.Contains(g); }
  // The MLP weight blocks (AdamW's decay applies to these only).
  bool IsMlpWeights(const double* block) const;

 private:
  // Whether the batch falls in the freeze after a bone re-initialisation.
  bool FrozenAfterReinit(int batch_index) const;
  // Holds group g constant (or frees it, unless the stage holds it).
  void HoldGroup(ParameterGroup g, bool hold);
  void AddBlock(ParameterGroup group, double* data, int size,
                std::unique_ptr<ceres::Manifold> manifold);
  void AddRegularizer(std::unique_ptr<ceres::CostFunction> cost, ceres::LossFunction* loss,
                      const std::vector<double*>& blocks);
  std::vector<double*>& Blocks(ParameterGroup g) { return groups_[static_cast<int>(g)]; }

  Model& model_;
  const StageConfig& stage_;
  RayBatch batch_;
  std::unique_ptr<ceres::Problem> problem_;
  std::array<std::vector<double*>, kNumParameterGroups> groups_;
  std::map<const double*, ParameterGroup> group_of_;
  ParameterGroupSet configured_constant_;  // the stage's and the extra groups
  ParameterGroupSet constant_;             // now (the delta-skinning schedule changes it)
  std::vector<double*> held_;
  std::array<std::unique_ptr<ceres::LossFunction>, kNumLossTerms> robust_;
  RayRobustLosses ray_robust_{};
  std::vector<ceres::ResidualBlockId> batch_blocks_;
  std::vector<ceres::ResidualBlockId> regularizer_blocks_;  // of batch_blocks_
  std::set<const double*> used_;                            // blocks read by the minibatch
  // The joint tree the bone transforms' articulated steps follow
  // (StageConfig::bone_steps_articulated; null otherwise): rebuilt from the
  // rest bones at every minibatch, read by every frame's manifold.
  std::unique_ptr<BoneTree> bone_tree_;
};

// The Ceres loss function of a robust-loss config (nullptr for none).
std::unique_ptr<ceres::LossFunction> MakeRobustLoss(const RobustLossConfig& config);

}  // namespace banmo
