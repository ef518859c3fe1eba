// The Adam step rule's gradient path (RayBatch::EvaluateGradient + the
// regularisers' cost functions + PlusJacobian^T per manifold block) against
// the reference path, ceres::Problem::Evaluate over full Jacobians
// (SolveOptions::adam_gradient_from_ceres): the same parameters after a few
// batches, with robust losses, manifolds (root poses, bones, bone
// transforms) and a constant group.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "banmo/optim/solver.h"
#include "tiny_solver_scene.h"

namespace banmo {
namespace {

const Dataset& TinyDataset() { return testing::TinyQuadrupedDataset(1); }

SolverConfig TinyAdamConfig(int iterations) {
  SolverConfig c = testing::TinySolverConfig(StepRule::kAdam, iterations);
  c.seed = 5;
  StageConfig& s = c.stages[0];
  s.batch_rays = 64;
  s.samples_per_ray = 12;
  s.adam.weight_decay = 1e-3;
  s.losses[LossTerm::kRgb].robust = {RobustLossType::kHuber, 0.05};
  s.losses[LossTerm::kCycle3d].robust = {RobustLossType::kCauchy, 0.1};
  s.losses[LossTerm::kBoneInside].robust = {RobustLossType::kSoftL1, 0.1};
  s.losses[LossTerm::kBoneJoint].weight = 0.5;
  s.losses[LossTerm::kBoneJoint].robust = {RobustLossType::kHuber, 0.05};
  s.constant = {ParameterGroup::kIntrinsics, ParameterGroup::kAppearance};
  return c;
}

using testing::AllParameters;

std::vector<double> Solve(const SolverConfig& config, bool from_ceres) {
  const Dataset& data = TinyDataset();
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  SolveOptions options;
  options.quiet = true;
  options.adam_gradient_from_ceres = from_ceres;
  const SolveResult r = solver.Run(options);
  EXPECT_TRUE(r.stages.at(0).finite);
  return AllParameters(solver.model());
}

void ExpectBatchedPathEqualsCeresPath(const SolverConfig& config) {
  const Dataset& data = TinyDataset();
  std::vector<double> initial;
  {
    auto model = MakeModelForDataset(data, config.model);
    initial = AllParameters(*model);
  }
  const std::vector<double> fast = Solve(config, false);
  const std::vector<double> reference = Solve(config, true);
  ASSERT_EQ(fast.size(), reference.size());
  ASSERT_EQ(fast.size(), initial.size());
  // The two gradients agree to rounding (tests/losses/ray_gradient_test.cc:
  // 1e-10); Adam divides by sqrt(v) + 1e-8, so a component's step changes by
  // about its gradient's relative error: after 4 steps of lr 3e-3 every
  // parameter agrees to 1e-9 of max(|value|, 1) (measured: ~1e-13). A
  // missing or wrong gradient term shows as differences ~lr.
  double max_diff = 0.0, max_step = 0.0;
  for (size_t i = 0; i < fast.size(); ++i) {
    max_diff = std::max(max_diff,
                        std::abs(fast[i] - reference[i]) / std::max(1.0, std::abs(reference[i])));
    max_step = std::max(max_step, std::abs(reference[i] - initial[i]));
  }
  EXPECT_GT(max_step, 1e-3);  // the steps are not trivially empty
  EXPECT_LE(max_diff, 1e-9) << "max step " << max_step;
}

TEST(AdamGradient, BatchedPathEqualsCeresEvaluatePath) {
  ExpectBatchedPathEqualsCeresPath(TinyAdamConfig(4));
}

// The same with the bone transforms on the articulated manifold (tangent
// 3 B + 3, deform/articulated_manifold.h).
TEST(AdamGradient, BatchedPathEqualsCeresEvaluatePathWithArticulatedBoneSteps) {
  SolverConfig config = TinyAdamConfig(4);
  config.stages[0].bone_steps_articulated = true;
  ExpectBatchedPathEqualsCeresPath(config);
}

}  // namespace
}  // namespace banmo
