// The full-Jet reference of a ray's loss terms: the same templated stages
// (losses/ray_functors.h, deform/bones.h, field/canonical_field.h) evaluated
// with Jets over EVERY parameter of the term, MLP weights included, through
// ceres::DynamicAutoDiffCostFunction. Correct by construction and slow (its
// cost grows with the number of weights, docs/design.md): it is the
// regression reference the mixed-mode RayBatch must equal, and the baseline of
// the Jacobian-assembly benchmark.
#pragma once

#include <ceres/cost_function.h>

#include <memory>

#include "banmo/losses/ray_batch.h"

namespace banmo {

// Reference cost function of `term` for ray `index` of `batch`, with the
// same parameter blocks (order and sizes) as batch.MakeCostFunction. The
// batch and its model must outlive it.
std::unique_ptr<ceres::CostFunction> MakeReferenceCostFunction(const RayBatch& batch, int index,
                                                               LossTerm term);

}  // namespace banmo
