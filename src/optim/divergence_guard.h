// The solver's divergence guard (private to the optim module; what it does
// is documented in docs/robustness.md). After every batch the losses, the
// parameters and the canonical bounds must be finite; otherwise the solve
// stops with a DivergenceError (exit 2) naming the stage, the batch and the
// term or parameter block that blew up, and the last good state is left as
// a checkpoint to resume from. On valid input it reads each parameter once
// per batch and changes nothing.
#pragma once

#include <Eigen/Geometry>
#include <string>

#include "banmo/io/dataset.h"
#include "banmo/model/model.h"
#include "banmo/optim/config.h"
#include "banmo/optim/solver.h"

namespace banmo::internal {

// Throws DivergenceError (without stage and batch) if a loss term of the
// batch is not finite (naming the term and its weight), else if a parameter
// block holds a non-finite value after the step (naming the block, the step
// rule and the learning rate), else if the canonical bounds are not finite.
void CheckFiniteAfterBatch(const TermLosses& losses, Model& model,
                           const Eigen::AlignedBox3d& bounds, const StageConfig& stage,
                           double learning_rate);

// A finite divergence: the batch's total loss above kLossRiseFactor times
// the stage's first batch total. `first_total` < 0 on the stage's first
// call (it is then set). The solver prints a warning (once per stage) and
// goes on: losses may rise when a schedule switches terms on.
inline constexpr double kLossRiseFactor = 1000.0;
bool LossRoseSharply(const TermLosses& losses, double* first_total);

// Throws InputError naming stages[i].sampling.flow_gaps if a stage with a
// flow loss asks for a gap the dataset does not have (its flow term would
// silently vanish); datasets without any flow are left alone.
void CheckFlowGaps(const SolverConfig& config, const Dataset& dataset);

// The message of a DivergenceError raised in stage `stage_index` (0-based)
// at `batch` (0-based) with `what`, and where the last good state is.
std::string DivergenceMessage(const StageConfig& stage, int stage_index, int num_stages, int batch,
                              const std::string& what, const std::string& checkpoint_note);

}  // namespace banmo::internal
