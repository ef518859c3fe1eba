// A model for a dataset (cameras, frame counts, scene scale and rough root
// poses from the data), and the motion-retargeting copy of a trained model's
// shared parameters into a new one (BANMo, Yang et al. CVPR 2022, Sec. 4.4).
#pragma once

#include <memory>
#include <string>

#include "banmo/io/dataset.h"
#include "banmo/model/model.h"

namespace banmo {

// A model for `dataset`: cameras and frame counts from the data, the
// canonical origin c at the object centre (EstimateObjectCentre) when
// options.recentre, else at the root origin; the scene scale s from
// options.scene_scale or estimated from the data (model/scene_scale.h);
// G0^t = the dataset's rough root pose * T(c), translations divided by s;
// MLPs and bones initialised from options.
std::unique_ptr<Model> MakeModelForDataset(const Dataset& dataset, const ModelOptions& options);

// Motion retargeting (paper Sec. 4.4): copies the shared parameters (canonical
// fields, beta, rest bones) of `from` into `to`; `to` takes `from`'s scene
// scale (its root translations are re-expressed in `from`'s model units) and
// canonical origin (its G0^t re-based on it; the two datasets' root frames
// are taken to be the same rig's).
// Throws InputError naming `source` if the two models' sizes differ.
void CopySharedParameters(const Model& from, Model* to, const std::string& source);

}  // namespace banmo
