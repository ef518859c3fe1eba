// The initial root poses' preparation before a solve, shared by `banmo
// solve` and the solver harness (banmo_trace), so both solve from the same
// poses: model.root_init_registration (registration/root_init_registration.h),
// then model.root_init_smoothing (registration/root_init_smoothing.h), each when
// enabled (docs/solver.md, "Videos without poses", "Smoothing rough
// initial poses").
#pragma once

#include <string>

#include "banmo/io/dataset.h"
#include "banmo/model/model.h"
#include "banmo/util/reporter.h"

namespace banmo {

// Registers and smooths `dataset`'s root_pose_init in place as `options`
// say. Deterministic, so a resumed solve gets the same poses. Reports one
// line per step to `reporter` (if not null; `banmo solve` prints them as
// "banmo solve: root-pose registration ..."), and where the dataset has
// ground truth, the initial poses' rotation error before and after each
// step that changes them.
void PrepareRootPoseInit(const ModelOptions& options, Dataset* dataset, LineReporter* reporter);

}  // namespace banmo
