// Levenberg-Marquardt steps by Ceres on the minibatch's residual blocks.
#include <ceres/solver.h>

#include <algorithm>

#include "step_rules.h"

namespace banmo {

void LmStep(const StepContext& c, const ParameterGroupSet& hold) {
  StageProblem& sp = *c.problem;
  const LmConfig& lm = c.stage->lm;
  sp.Hold(hold);
  const bool schur = lm.linear_solver == LinearSolverType::kIterativeSchur;
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = schur ? ceres::ITERATIVE_SCHUR : ceres::CGNR;
  so.preconditioner_type = schur ? ceres::SCHUR_JACOBI : ceres::IDENTITY;
  so.max_linear_solver_iterations = lm.max_cg_iterations;
  so.min_linear_solver_iterations = 1;
  so.max_num_iterations = lm.iterations_per_batch;
  so.initial_trust_region_radius = c.state->lm_radius > 0 ? c.state->lm_radius : lm.initial_radius;
  so.max_trust_region_radius = lm.max_radius;
  so.num_threads = 1;  // as for Evaluate: the heavy work is in RayBatch
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.update_state_every_iteration = true;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &sp.problem(), &summary);
  if (!summary.iterations.empty()) {
    c.state->lm_radius = std::min(summary.iterations.back().trust_region_radius, lm.max_radius);
  }
  sp.Restore();
  sp.batch().Invalidate();
}

}  // namespace banmo
