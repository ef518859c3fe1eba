// The step rules of a stage (docs/solver.md): how one minibatch moves the
// parameters. One file each: adam_step.cc, lm_step.cc, alternate_step.cc.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "banmo/optim/config.h"
#include "solver_state.h"
#include "stage_problem.h"

namespace banmo {

// What a step needs besides the stage's problem.
struct StepContext {
  StageProblem* problem = nullptr;
  const StageConfig* stage = nullptr;
  SolverState* state = nullptr;  // Adam moments, LM radius
  int batch = 0;                 // batch index within the stage (learning-rate schedule)
  // Adam's gradient from ceres::Problem::Evaluate (SolveOptions).
  bool adam_gradient_from_ceres = false;
  // Block names (Model::ForEachBlock): the keys of the Adam moments.
  const std::map<const double*, std::string>* block_names = nullptr;
};

// The learning rate of batch `batch` of `batches` (a.schedule).
// One-cycle (Smith 2018, as in BANMo's training): linear warm-up from lr/25
// to lr over warmup_fraction, then cosine decay to lr * final_lr_fraction.
double LearningRate(const AdamConfig& a, int batch, int batches);

// AdamW on `blocks` (tangent-space steps through each block's manifold).
// after_gradient (optional) runs once the gradient is known and before the
// update, when the batch's value cache holds the residuals at the step's
// starting point.
void AdamStep(const StepContext& context, const std::vector<double*>& blocks,
              const std::function<void()>& after_gradient);

// One Ceres Levenberg-Marquardt solve (lm.iterations_per_batch iterations)
// on the minibatch with the groups in `hold` constant; the trust-region
// radius is carried in the state from batch to batch, capped.
void LmStep(const StepContext& context, const ParameterGroupSet& hold);

// Adam on every block but the per-frame root corrections (and, with
// pose_solve.bones, the bone transforms): the stage's pose solves move
// those (Solver::SolvePoses).
void AlternateStep(const StepContext& context, const std::function<void()>& record_losses);

// The stage's step rule on the current minibatch. record_losses runs once
// with the batch's residuals at the step's starting point in the cache.
void TakeStep(const StepContext& context, const std::function<void()>& record_losses);

}  // namespace banmo
