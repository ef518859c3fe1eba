#include "divergence_guard.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "banmo/losses/loss_table.h"
#include "banmo/util/enum_names.h"
#include "banmo/util/error.h"

namespace banmo::internal {
namespace {

// The configured weight of the loss term called `name`, if there is one.
bool TermWeight(const StageConfig& stage, const std::string& name, double* weight) {
  for (int t = 0; t < kNumLossTerms; ++t) {
    const auto term = static_cast<LossTerm>(t);
    if (name == LossTermName(term)) {
      *weight = stage.losses[term].weight;
      return true;
    }
  }
  return false;
}

}  // namespace

void CheckFiniteAfterBatch(const TermLosses& losses, Model& model,
                           const Eigen::AlignedBox3d& bounds, const StageConfig& stage,
                           double learning_rate) {
  for (const auto& [name, value] : losses) {
    if (std::isfinite(value)) continue;
    double weight = 0;
    std::ostringstream os;
    os << "the loss term '" << name << "' is " << value << " at the batch's start";
    if (TermWeight(stage, name, &weight)) os << " (losses." << name << ".weight " << weight << ")";
    ThrowDivergenceError(os.str());
  }
  std::string bad_block;
  model.ForEachBlock([&](const std::string& name, double* data, int size) {
    if (!bad_block.empty()) return;
    for (int k = 0; k < size; ++k) {
      if (!std::isfinite(data[k])) {
        bad_block = name;
        return;
      }
    }
  });
  if (!bad_block.empty()) {
    // The largest term is the likeliest culprit (its gradient drove the step).
    std::string largest;
    double largest_value = -1;
    for (const auto& [name, value] : losses) {
      if (value > largest_value) largest = name, largest_value = value;
    }
    std::ostringstream os;
    os << "the step (" << EnumName(stage.step_rule) << ", learning rate " << learning_rate
       << ") left the parameter block '" << bad_block
       << "' with a non-finite value (every loss term was finite before it";
    double weight = 0;
    if (!largest.empty() && TermWeight(stage, largest, &weight)) {
      os << "; the largest was '" << largest << "' = " << largest_value << ", losses." << largest
         << ".weight " << weight;
    }
    os << ")";
    ThrowDivergenceError(os.str());
  }
  if (!bounds.min().allFinite() || !bounds.max().allFinite()) {
    ThrowDivergenceError("the canonical bounds are not finite");
  }
}

void CheckFlowGaps(const SolverConfig& config, const Dataset& dataset) {
  if (dataset.flow_gaps.empty()) return;
  for (std::size_t s = 0; s < config.stages.size(); ++s) {
    const StageConfig& stage = config.stages[s];
    if (!(stage.losses[LossTerm::kFlow].weight > 0)) continue;
    for (int gap : stage.sampling.flow_gaps) {
      if (std::find(dataset.flow_gaps.begin(), dataset.flow_gaps.end(), gap) !=
          dataset.flow_gaps.end()) {
        continue;
      }
      std::ostringstream have;
      for (int g : dataset.flow_gaps) have << (have.tellp() > 0 ? ", " : "") << g;
      ThrowInputError("stages[", s, "] ('", stage.name, "').sampling.flow_gaps: gap ", gap,
                      " is not in the dataset, which has flow for gaps [", have.str(),
                      "] (its flow term would silently vanish)");
    }
  }
}

bool LossRoseSharply(const TermLosses& losses, double* first_total) {
  double total = 0;
  for (const auto& entry : losses) total += entry.second;
  if (*first_total < 0) {
    *first_total = total;
    return false;
  }
  return total > kLossRiseFactor * *first_total && total > 1e-12;
}

std::string DivergenceMessage(const StageConfig& stage, int stage_index, int num_stages, int batch,
                              const std::string& what, const std::string& checkpoint_note) {
  std::ostringstream os;
  os << "the solve diverged in stage '" << stage.name << "' (" << stage_index + 1 << "/"
     << num_stages << "), batch " << batch + 1 << "/" << stage.batches << ": " << what << ". "
     << checkpoint_note
     << " Lower the stage's learning rate (adam.lr) or the loss weight named above and "
        "solve again.";
  return os.str();
}

}  // namespace banmo::internal
