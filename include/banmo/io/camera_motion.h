// The camera's own rotation along a video, from the background's optical
// flow (`banmo prepare`; docs/dataset.md, "Camera rotation from the
// background"). A hand-held or panning camera that follows its subject turns
// by tens of degrees (DAVIS parkour 147 deg, libby 73 deg); root poses that
// ignore it ask the shape to explain the turn.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "banmo/io/dataset.h"

namespace banmo {

struct CameraRotationOptions {
  // Background: pixels farther than this from the object (mask dilated by
  // a square of side 2 m + 1), so that flow smeared across the object's
  // boundary is not taken for the background's.
  int mask_margin_px = 7;
  // At most about this many background pixels a frame pair (a regular
  // grid), with a valid forward-backward check.
  int max_points = 4000;
  // RANSAC threshold of both models (pixels: the homography's transfer
  // error, the essential matrix's distance to the epipolar line): DIS flow
  // of a textured background is good to a fraction of a pixel.
  double ransac_threshold_px = 1.0;
  // A step is trusted when the model it takes keeps at least this many
  // inliers and this fraction of the sampled pixels; else the camera is
  // taken to have kept its orientation over the step.
  int min_inliers = 100;
  double min_inlier_fraction = 0.3;
  // A larger turn between consecutive frames is taken as a failed fit.
  double max_step_deg = 20.0;
  // The homography's rotation is kept when it explains at least this
  // fraction of the pixels the essential matrix explains (same threshold):
  // a camera that only turns, or a distant background, fits a homography,
  // and the essential matrix's translation is then undetermined. Below it
  // the background shows parallax (a camera that moves, a near background)
  // and the rotation comes from the essential matrix.
  double homography_preference = 0.9;
  void Check() const;  // throws InputError naming the field
};

struct CameraRotations {
  // camera_t_from_camera_0 for every frame t (identity for t = 0).
  std::vector<Eigen::Matrix3d> camera_from_first;
  // Per step t -> t + 1: the turn (degrees; 0 where the step failed) and
  // whether the fit was trusted.
  std::vector<double> step_deg;
  std::vector<bool> step_ok;
  std::vector<bool> step_essential;  // the rotation came from the essential matrix
  int FailedSteps() const;
  int EssentialSteps() const;
};

// Rotations of the camera from frame 0 to each frame of `video` (masks,
// intrinsics and gap-1 forward flow set): for each consecutive pair, the
// background pixels' flow is fitted with RANSAC by a homography H and by an
// essential matrix E. If H keeps `homography_preference` of E's inliers,
// R = nearest rotation to K^-1 H K (SVD), the homography of a camera that
// turns about its centre; else R is E's rotation (cv::recoverPose, the
// decomposition with the points in front of both cameras). The steps are
// chained: R_{t+1 <- 0} = R_{t+1 <- t} R_{t <- 0}. Steps without enough
// background (the object fills the view, a textureless sky) count as no
// turn. Returns identity rotations if the video has no gap-1 flow.
CameraRotations EstimateCameraRotations(const Video& video, const CameraRotationOptions& options);

// Sets every frame's initial root rotation to camera_t_from_camera_0: the
// object keeps one orientation in the world and the camera turns about it.
// The translations (on the mask-centroid rays) are kept.
void RotateRootsWithCamera(const CameraRotations& rotations, Video* video);

}  // namespace banmo
