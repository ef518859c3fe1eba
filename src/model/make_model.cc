#include "banmo/model/make_model.h"

#include <algorithm>

#include "banmo/model/scene_scale.h"
#include "banmo/util/error.h"

namespace banmo {

std::unique_ptr<Model> MakeModelForDataset(const Dataset& dataset, const ModelOptions& options) {
  std::vector<int> frames;
  std::vector<PinholeCamera> cameras;
  for (const Video& v : dataset.videos) {
    frames.push_back(static_cast<int>(v.frames.size()));
    cameras.push_back(v.camera);
  }
  auto model = std::make_unique<Model>(options, frames, cameras);
  // The canonical origin at the object centre (root frame, dataset units).
  const Eigen::Vector3d centre =
      options.recentre ? EstimateObjectCentre(dataset).centre : Eigen::Vector3d::Zero();
  // Model units = dataset units / s (model/scene_scale.h).
  const double s = ResolveSceneScale(dataset, options, centre);
  model->set_scene_scale(s);
  model->set_canonical_origin(centre / s);
  for (size_t v = 0; v < dataset.videos.size(); ++v) {
    for (size_t t = 0; t < dataset.videos[v].frames.size(); ++t) {
      Pose& root_init = model->frame(v, t).root_init;
      root_init = PoseWithOriginAt(dataset.videos[v].frames[t].root_pose_init, centre);
      for (int k = 0; k < 3; ++k) root_init[kPoseT + k] /= s;
    }
  }
  return model;
}

void CopySharedParameters(const Model& from, Model* to, const std::string& source) {
  if (from.sdf_size() != to->sdf_size() || from.color_size() != to->color_size() ||
      from.embedding_size() != to->embedding_size() || from.bones_size() != to->bones_size() ||
      from.delta_skinning_size() != to->delta_skinning_size() ||
      from.pose_code_size() != to->pose_code_size()) {
    ThrowInputError(source,
                    ": the model's sizes (MLP widths, bones) differ from the config's "
                    "model section; retarget with the config the model was trained with");
  }
  std::copy(from.sdf(), from.sdf() + from.sdf_size(), to->sdf());
  std::copy(from.color(), from.color() + from.color_size(), to->color());
  std::copy(from.embedding(), from.embedding() + from.embedding_size(), to->embedding());
  std::copy(from.bones(), from.bones() + from.bones_size(), to->bones());
  *to->log_beta() = *from.log_beta();
  // Delta skinning: MLP_Delta and the rest-pose code are shared; the new
  // frames' pose codes are fitted.
  std::copy(from.delta_skinning_params(), from.delta_skinning_params() + from.delta_skinning_size(),
            to->delta_skinning_params());
  std::copy(from.rest_pose_code(), from.rest_pose_code() + from.pose_code_size(),
            to->rest_pose_code());
  // The shared shape is in `from`'s model units: `to` takes its scene scale,
  // its root translations re-expressed (exact for equal scales).
  const double ratio = to->scene_scale() / from.scene_scale();
  // And its canonical origin moved to `from`'s (both in the root frame the
  // two datasets share): G0 * T(c_from - c_to), c_to in `from`'s units.
  const Eigen::Vector3d shift = from.canonical_origin() - ratio * to->canonical_origin();
  for (int v = 0; v < to->num_videos(); ++v) {
    for (FrameParameters& f : to->video(v).frames) {
      for (int k = 0; k < 3; ++k) {
        f.root_init[kPoseT + k] *= ratio;
        f.root_delta[kPoseT + k] *= ratio;
      }
      f.root_init = PoseWithOriginAt(f.root_init, shift);
    }
  }
  to->set_scene_scale(from.scene_scale());
  to->set_canonical_origin(from.canonical_origin());
}

}  // namespace banmo
