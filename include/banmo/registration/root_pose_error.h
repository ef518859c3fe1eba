// Root-pose errors against a dataset's ground-truth root poses (synthetic
// datasets have them): the rotation error of each frame's G^t after one
// global alignment, since the canonical frame the solver settles in may be
// turned against the ground truth's root frame as a whole.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "banmo/io/dataset.h"
#include "banmo/model/model.h"

namespace banmo {

struct RootPoseErrors {
  struct FrameError {
    int video = 0;
    int frame = 0;
    double rotation_deg = 0.0;        // angle between R_gt^t A and R^t
    double video_rotation_deg = 0.0;  // the same with the video's own A (video_aligned_mean_deg)
  };
  std::vector<FrameError> frames;  // usable frames with a ground-truth pose
  // A: the rotation of the model's canonical frame in the ground truth's
  // root frame, R^t ~ R_gt^t A for all t (the chordal L2 mean of
  // R_gt^t^T R^t, projected onto SO(3)).
  Eigen::Matrix3d alignment = Eigen::Matrix3d::Identity();
  double alignment_deg = 0.0;  // its angle
  double mean_deg = 0.0;
  double p90_deg = 0.0;  // 90th percentile (nearest rank)
  double max_deg = 0.0;
  // The mean error when each video is aligned on its own (its own A): how
  // well the frames of a video agree with each other, whatever the videos'
  // relative rotations.
  double video_aligned_mean_deg = 0.0;
};

// The errors of `model`'s root poses (Model::RootPose) against
// `dataset`'s root_pose_gt; nullopt when no usable frame has one. The model
// and the dataset must have the same videos and frames.
std::optional<RootPoseErrors> ComputeRootPoseErrors(const Model& model, const Dataset& dataset);

// The same for the body pose: each frame's root composed with the mean
// rotation of its bone transforms, G^t * mean_b(J_b^t) (MeanBoneRotation,
// deform/bones.h; equal weights). A frame's residuals do not change when
// all its bones turn by M and its root by M^-1, so the root alone can
// drift while the object stays registered; the body pose does not see that
// freedom (the root's error is what a user of the root poses sees, the
// body's is whether the object is registered). Equals the root's errors
// without bones.
std::optional<RootPoseErrors> ComputeBodyPoseErrors(const Model& model, const Dataset& dataset);

// The errors of the dataset's own initial root poses (root_pose_init).
std::optional<RootPoseErrors> InitialRootPoseErrors(const Dataset& dataset);

// CSV: video,frame,rotation_error_deg, one line per frame; with `body`
// (same frames) a fourth column body_rotation_error_deg.
std::string RootPoseErrorsCsv(const RootPoseErrors& errors, const RootPoseErrors* body = nullptr);

}  // namespace banmo
