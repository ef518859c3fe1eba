// Which density turns the SDF into rendering weights
// (volume/volume_rendering.h: CompositeWeights). A model option
// (`model.density`), kept apart from the renderer so model.h stays light.
#pragma once

#include <utility>

#include "banmo/util/enum_names.h"

namespace banmo {

enum class DensityModel {
  kVolSdf,  // VolSDF's Laplace-CDF density (BANMo's), sigma = Psi_beta(-sdf) / beta
  kNeus,    // NeuS's interval opacities from sigmoid(sdf / beta)
};

template <>
struct EnumNames<DensityModel> {
  static constexpr std::pair<DensityModel, const char*> kNames[] = {
      {DensityModel::kVolSdf, "volsdf"}, {DensityModel::kNeus, "neus"}};
};

}  // namespace banmo
