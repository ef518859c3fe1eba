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
    double rotation_deg = 0.0;  // angle between R_gt^t A and R^t
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
};

// The errors of `model`'s root poses (Model::RootPose) against
// `dataset`'s root_pose_gt; nullopt when no usable frame has one. The model
// and the dataset must have the same videos and frames.
std::optional<RootPoseErrors> ComputeRootPoseErrors(const Model& model, const Dataset& dataset);

// The errors of the dataset's own initial root poses (root_pose_init).
std::optional<RootPoseErrors> InitialRootPoseErrors(const Dataset& dataset);

// CSV: video,frame,rotation_error_deg, one line per frame.
std::string RootPoseErrorsCsv(const RootPoseErrors& errors);

}  // namespace banmo
