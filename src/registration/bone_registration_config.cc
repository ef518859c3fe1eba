#include "banmo/registration/bone_registration_config.h"

namespace banmo {

BoneRegistrationConfig BoneRegistrationConfig::AfterLastBatch() const {
  BoneRegistrationConfig out = *this;
  out.match_weight = after_last_batch.match_weight.value_or(match_weight);
  out.mask_weight = after_last_batch.mask_weight.value_or(mask_weight);
  out.coverage_weight = after_last_batch.coverage_weight.value_or(coverage_weight);
  return out;
}

}  // namespace banmo
