// The alternate step rule and the dispatch of a stage's step rule.
#include "step_rules.h"

namespace banmo {

void AlternateStep(const StepContext& c, const std::function<void()>& record_losses) {
  // Adam on every block but the per-frame root corrections (and, with
  // pose_solve.bones, the bone transforms), which only the stage's
  // frame-major pose solves move (Solver::SolvePoses, pose_solve.every /
  // at): a Gauss-Newton step on them from a minibatch sees a handful of
  // each frame's rays and collapsed the surface (docs/solver.md, "The
  // alternate step rule").
  using G = ParameterGroup;
  ParameterGroupSet others;
  for (int g = 0; g < kNumParameterGroups; ++g) {
    const G group = static_cast<G>(g);
    if (group == G::kRoot || (group == G::kBonesT && c.stage->pose_solve.bones)) continue;
    others.Insert(group);
  }
  AdamStep(c, c.problem->FreeBlocks(others), record_losses);
}

void TakeStep(const StepContext& c, const std::function<void()>& record_losses) {
  if (c.stage->step_rule == StepRule::kAdam) {
    AdamStep(c, c.problem->FreeBlocks({}), record_losses);
    return;
  }
  if (c.stage->step_rule == StepRule::kAlternate) {
    AlternateStep(c, record_losses);
    return;
  }
  c.problem->batch().EvaluateAll(false);
  record_losses();
  LmStep(c, {});
}

}  // namespace banmo
