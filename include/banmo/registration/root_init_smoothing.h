// Temporal smoothing of rough initial root poses (issue 18; docs/solver.md,
// "Smoothing rough initial poses").
//
// A video's frames are consecutive, so its true root rotations form a
// smooth track: on the synthetic scenes the second difference of the
// rotation track (the change of the frame-to-frame rotation) stays below
// 1.6 deg per frame^2, while per-frame pose noise of mean 50 deg makes it
// about 110. Each video's rotations R_t = R0_t Exp(d_t) (R0_t the rough
// pose, d_t a rotation vector on the object side, as the solver's root
// correction) minimise, with Ceres' Levenberg-Marquardt,
//
//   sum_t rho(|d_t|^2 / sigma^2) + sum_t |v_t - v_{t-1}|^2 / a^2,
//   v_t = Log(R_t^T R_{t+1})  (the frame-to-frame rotation, object side),
//
// rho Cauchy's loss with scale `robust_sigmas` (a frame far off the track
// stops pulling it), `a` the prior's acceleration and sigma the noise of
// the rough track, estimated from it: the median of |v_t - v_{t-1}| over
// the rough track, divided by that of 6 sigma^2 chi^2_3 (sqrt(6) x 1.538).
// A track none of whose second differences exceeds `a` is already as
// smooth as the prior expects and is left exactly as it is (exact poses:
// the solve is the same as without smoothing); others are pulled onto a
// track whose acceleration is about `a`, exact ones with a stiff data term
// (hundredths of a degree on `quad`). Translations are left as they are.
#pragma once

#include <vector>

#include "banmo/geometry/se3.h"
#include "banmo/io/dataset.h"
#include "banmo/model/root_smoothing_options.h"

namespace banmo {

struct RootTrackSmoothing {
  double noise_deg = 0.0;             // sigma, the estimated per-axis noise of the rough track
  double max_acceleration_deg = 0.0;  // the rough track's largest second difference
  bool smoothed = false;              // false: too short, or already smooth (left as it was)
  double mean_change_deg = 0.0;       // mean rotation between a rough and a smoothed pose
  double max_change_deg = 0.0;
  int iterations = 0;  // Levenberg-Marquardt iterations (0: left as it was)
};

// The per-axis rotation noise (degrees) of a track of camera_from_root
// poses in frame order, estimated from its second differences as above (0
// for fewer than 3 poses or a constant track).
double RootTrackNoiseDeg(const std::vector<Pose>& poses);

// Smooths the rotations of one track of camera_from_root poses (in frame
// order) in place; tracks of fewer than 3 poses are left as they are.
// Translations are unchanged. `observed` (empty: all) says which poses are
// data: the others have no data term and are placed by the prior alone.
RootTrackSmoothing SmoothRootTrack(const RootSmoothingOptions& options, std::vector<Pose>* poses,
                                   const std::vector<bool>& observed = {});

// SmoothRootTrack on each video's root_pose_init (frames in index order,
// skipped frames included: their poses are data like the others, except
// held-out frames' (io/holdout.h), which are no observation). One result
// per video.
std::vector<RootTrackSmoothing> SmoothRootPoseInit(const RootSmoothingOptions& options,
                                                   Dataset* dataset);

}  // namespace banmo
