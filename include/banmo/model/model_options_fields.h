// The fields of ModelOptions and of the option structs inside it, listed
// once: VisitFields(visitor, options) calls visitor(key, field) for every
// field in order. The YAML walker (util/yaml.h) walks these lists for the
// solver config (src/optim/config.cc, section `model:`) and the model file
// (model/model_file.h, key `options:`), so a field is read and written
// under the same key everywhere by construction. Keys equal the field names.
#pragma once

#include "banmo/model/model.h"

namespace banmo {

template <class V>
void VisitFields(V& v, PositionalEncodingOptions& o) {
  v("num_bands", o.num_bands);
  v("include_input", o.include_input);
  v("base_frequency", o.base_frequency);
}

template <class V>
void VisitFields(V& v, CanonicalFieldOptions& o) {
  v("position_encoding", o.position_encoding);
  v("sdf_width", o.sdf_width);
  v("sdf_layers", o.sdf_layers);
  v("geometry_feature_dim", o.geometry_feature_dim);
  v("color_width", o.color_width);
  v("color_layers", o.color_layers);
  v("use_view_direction", o.use_view_direction);
  v("view_encoding", o.view_encoding);
  v("appearance_code_dim", o.appearance_code_dim);
  v("embedding_width", o.embedding_width);
  v("embedding_layers", o.embedding_layers);
  v("activation", o.activation);
  v("softplus_beta", o.softplus_beta);
  v("init_sphere_radius", o.init_sphere_radius);
}

template <class V>
void VisitFields(V& v, DeltaSkinningOptions& o) {
  v("enabled", o.enabled);
  v("width", o.width);
  v("hidden_layers", o.hidden_layers);
  v("num_bands", o.num_bands);
  v("pose_code_dim", o.pose_code_dim);
  v("code_init_std", o.code_init_std);
}

template <class V>
void VisitFields(V& v, AutoSizeOptions& o) {
  v("enabled", o.enabled);
  v("max_bones", o.max_bones);
  v("grow_at", o.grow_at);
  v("error_ratio", o.error_ratio);
  v("eval_rays", o.eval_rays);
  v("max_width", o.max_width);
}

template <class V>
void VisitFields(V& v, RootSmoothingOptions& o) {
  v("enabled", o.enabled);
  v("acceleration_deg", o.acceleration_deg);
  v("robust_sigmas", o.robust_sigmas);
}

template <class V>
void VisitFields(V& v, RootRegistrationOptions& o) {
  v("enabled", o.enabled);
  v("always", o.always);
  v("references", o.references);
}

template <class V>
void VisitFields(V& v, ModelOptions& o) {
  v("field", o.field);
  v("num_bones", o.num_bones);
  v("init_bone_scale", o.init_bone_scale);
  v("init_beta", o.init_beta);
  v("density", o.density);
  v("seed", o.seed);
  v("delta_skinning", o.delta_skinning);
  v("scene_scale", o.scene_scale);
  v("recentre", o.recentre);
  v("auto_size", o.auto_size);
  v("root_init_smoothing", o.root_init_smoothing);
  v("root_init_registration", o.root_init_registration);
}

}  // namespace banmo
