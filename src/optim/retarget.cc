#include "banmo/optim/retarget.h"

#include "banmo/model/make_model.h"
#include "banmo/optim/checkpoint.h"

namespace banmo {

std::vector<ParameterGroup> RetargetConstantGroups() {
  return {ParameterGroup::kSdf,     ParameterGroup::kColor, ParameterGroup::kEmbedding,
          ParameterGroup::kLogBeta, ParameterGroup::kBones, ParameterGroup::kDeltaSkinning};
}

bool SwitchOffAutoSizeForRetarget(SolverConfig* config) {
  const bool was_on = config->model.auto_size.enabled;
  config->model.auto_size.enabled = false;
  return was_on;
}

std::unique_ptr<Model> LoadRetargetSource(const std::string& dir, bool sized_from_source,
                                          ModelOptions* options) {
  CheckpointInfo info;
  std::unique_ptr<Model> source = LoadCheckpoint(dir, &info);
  if (sized_from_source) {
    options->num_bones = source->num_bones();
    options->field.sdf_width = source->options().field.sdf_width;
    options->field.color_width = source->options().field.color_width;
  }
  return source;
}

void ApplyRetarget(const Model& source, const std::string& dir, Model* model,
                   SolveOptions* options) {
  CopySharedParameters(source, model, dir);
  options->extra_constant = RetargetConstantGroups();
}

}  // namespace banmo
