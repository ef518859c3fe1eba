// The alternate step rule and the dispatch of a stage's step rule.
#include "step_rules.h"

namespace banmo {

void AlternateStep(const StepContext& c) {
  // Fields and codes by Adam (MLP_Delta and its pose codes are fields),
  // then the coupled poses and bones by LM.
  using G = ParameterGroup;
  const ParameterGroupSet fields = {G::kSdf,        G::kColor,         G::kEmbedding, G::kLogBeta,
                                    G::kAppearance, G::kDeltaSkinning, G::kPoseCode};
  AdamStep(c, c.problem->FreeBlocks(fields), nullptr);
  LmStep(c, fields);
}

void TakeStep(const StepContext& c, const std::function<void()>& record_losses) {
  if (c.stage->step_rule == StepRule::kAdam) {
    AdamStep(c, c.problem->FreeBlocks({}), record_losses);
    return;
  }
  c.problem->batch().EvaluateAll(false);
  record_losses();
  if (c.stage->step_rule == StepRule::kLm) {
    LmStep(c, {});
  } else {
    AlternateStep(c);
  }
}

}  // namespace banmo
