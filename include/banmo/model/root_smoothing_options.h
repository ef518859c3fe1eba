// Options of the temporal smoothing of rough initial root poses (config key
// model.root_init_smoothing; the algorithm is in registration/root_init_smoothing.h,
// docs/solver.md "Smoothing rough initial poses").
#pragma once

namespace banmo {

struct RootSmoothingOptions {
  // Whether `banmo solve` smooths each video's root_pose_init track before
  // the model is made from it.
  bool enabled = false;
  // The expected size of the second difference of a true rotation track, in
  // degrees per frame^2 (> 0): the prior's scale. The synthetic scenes'
  // tracks (camera orbits, walking roots) have 0.3-1.6.
  double acceleration_deg = 2.0;
  // The Cauchy scale of a frame's data term, in units of the estimated noise
  // (> 0): frames further than this from the smoothed track count less.
  double robust_sigmas = 3.0;
};

}  // namespace banmo
