// Registration of root poses from pixel features, for videos without poses
// (issue 18; docs/solver.md, "Videos without poses").
//
// A pixel feature (DensePose CSE, or the synthetic scenes' stand-in) is a
// function of the canonical surface point it shows, the same in every
// frame of every video. So features track surface points across all frames
// without any pose, and the rotations follow from the tracks as in
// structure from motion:
//
// 1. References: `references` features spread over the feature space
//    (farthest-point sampling of a fixed random subset of the object
//    pixels' features).
// 2. Tracks: in each frame each reference is observed at the soft-argmin of
//    its feature distance over the object pixels (weights
//    exp(-(d^2 - d_min^2) / (2 x 0.1^2))), accepted when its best distance
//    is below 0.3 and the weights' spatial spread below 3 px (a unique
//    match; the synthetic features' per-pixel noise is about 0.2 in norm).
// 3. Affine factorisation: under a weak-perspective camera the observations
//    u_tp = s_t R_t[0:2] X_p + b_t. Alternating least squares over frames
//    (an affine 2 x 4 camera projected onto s x two orthonormal rows) and
//    points, from three random starts, keeps the lowest error: missing
//    observations are simply absent, so tracks need not be complete.
// 4. Bundle adjustment (Ceres, DENSE_SCHUR, Cauchy loss of scale 2 px) with
//    the full perspective camera, from the factorisation and from its depth
//    reversal (R -> D R D, X -> D X, D = diag(1, 1, -1), which a
//    weak-perspective camera cannot tell apart); the lower cost wins.
// 5. Which videos take it: with initial poses that carry rotations, a
//    video keeps them unless they are noisier than the registered track
//    (the noise of each track estimated from its second differences, as
//    the smoothing does: exact tracks 0.3 deg, registered ones 0.5-0.7,
//    Gaussian noise of mean 20 deg about 12).
// 6. The gauge: the registered rotations are turned as a whole onto the
//    initial ones of the videos kept (all videos' when none is kept; their
//    chordal L1 mean) and translations are scaled so that their median
//    depth equals the initial poses' median depth.
//
// Deterministic (fixed seeds, one thread), so a resumed solve gets the same
// poses. Frames with fewer than 6 observations take the pose of the nearest
// registered frame of their video.
#pragma once

#include <string>
#include <vector>

#include "banmo/io/dataset.h"
#include "banmo/model/root_registration_options.h"

namespace banmo {

struct VideoRegistration {
  double initial_noise_deg = 0.0;     // the initial track's noise (RootTrackNoiseDeg)
  double registered_noise_deg = 0.0;  // the registered track's
  bool replaced = false;              // whether the video's initial poses were replaced
};

struct RootRegistration {
  bool registered = false;  // the registration ran (the poses changed only where `replaced`)
  std::string reason;       // why not (registered == false)
  int frames = 0;           // frames registered from their own observations
  int filled = 0;  // frames replaced with a neighbour's pose (skipped, too few observations)
  int references = 0;
  double observations_per_frame = 0.0;
  double affine_rms_px = 0.0;       // factorisation's RMS reprojection error
  double median_residual_px = 0.0;  // bundle adjustment's median |residual|
  double cost = 0.0;                // final bundle-adjustment cost of the kept solution
  double mirror_cost = 0.0;         // ... and of its depth reversal
  bool ambiguous = false;           // cost > 0.8 mirror_cost
  int iterations = 0;               // bundle-adjustment iterations of the kept solution
  std::vector<VideoRegistration> videos;
};

// True when some two usable frames of the dataset have different initial
// root rotations (more than 1e-6 rad apart).
bool RootPosesCarryRotation(const Dataset& dataset);

// Registers every video's frames from their features and replaces the
// rotations and translations of root_pose_init (all frames, skipped ones
// included) of the videos that take the registration: every video when the
// initial poses carry no rotation (RootPosesCarryRotation) or
// options.always; otherwise a video whose initial rotation track is more
// than twice as noisy as its registered one (RootTrackNoiseDeg: exact
// poses are kept exactly as they are, rough ones replaced), unless the
// registration is ambiguous. Leaves the dataset unchanged and says why when
// it cannot: a usable frame without features, fewer than 2 usable frames,
// or a video none of whose frames has enough observations.
RootRegistration RegisterRootPoseInit(const RootRegistrationOptions& options, Dataset* dataset);

}  // namespace banmo
