// The in-memory dataset: several unsynchronised videos of one object, with
// masks, optical flow, 16-channel pixel features and rough root poses.
// The on-disk layout is documented in docs/dataset.md; LoadDataset validates
// everything and WriteDataset writes it atomically (temp folder, rename).
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "banmo/geometry/camera.h"
#include "banmo/geometry/mesh.h"
#include "banmo/geometry/se3.h"

namespace banmo {

// Channels of the pixel features (the stand-in for DensePose CSE).
inline constexpr int kFeatureDim = 16;

// Mask values.
inline constexpr unsigned char kMaskBackground = 0;
inline constexpr unsigned char kMaskIgnore = 128;  // unknown: no silhouette loss here
inline constexpr unsigned char kMaskObject = 255;

// Optical flow from frame t to frame t + gap of the same video (gap < 0:
// backward flow). flow(y, x) = (du, dv) in pixels, so pixel (u, v) of frame t
// moves to (u + du, v + dv). valid(y, x) = 255 where the pixel is visible in
// both frames (not occluded, inside the image), 0 elsewhere.
struct FlowField {
  int gap = 1;
  cv::Mat flow;   // CV_16FC2 (half floats: compact in memory; exact to ~1/32 px below 64 px)
  cv::Mat valid;  // CV_8UC1
};

struct Frame {
  int index = 0;        // frame index within its video (0-based)
  cv::Mat rgb;          // CV_8UC3, RGB channel order (not OpenCV's BGR)
  cv::Mat mask;         // CV_8UC1 with values kMaskBackground/Ignore/Object
  cv::Mat features;     // CV_16FC(kFeatureDim) (half floats); zero outside the mask; empty if absent
  std::vector<FlowField> flows;  // one per configured gap and direction present
  cv::Mat depth;        // CV_32FC1 camera z (scene units), 0 = background; empty if absent
  Pose root_pose_init = PoseIdentity();  // camera_from_root, rough initialisation G0^t
  std::optional<Pose> root_pose_gt;      // camera_from_root ground truth (synthetic)
  std::string gt_mesh_path;              // posed GT mesh (PLY, camera coords); empty if absent
  bool skip = false;                     // empty mask: warned about and skipped

  // The flow field for `gap`, or nullptr if absent.
  const FlowField* FlowForGap(int gap) const;
};

struct Video {
  std::string name;
  PinholeCamera camera;
  std::vector<Frame> frames;
};

struct Dataset {
  std::string root;            // folder it was loaded from (empty if in memory)
  std::vector<int> flow_gaps;  // positive gaps; each has forward and backward flow
  std::vector<Video> videos;

  int NumFrames() const;
};

struct LoadOptions {
  bool load_features = true;  // features are the largest part; skip if unused
  bool load_flow = true;
  bool load_depth = false;  // depth is ground truth, only tests need it
};

// Loads and validates the dataset in `dir`. Throws InputError naming the file
// and what was expected on any problem (see docs/dataset.md). Frames with an
// empty mask are warned about and marked skip.
Dataset LoadDataset(const std::string& dir, const LoadOptions& options = {});

// Writes `dataset` to `dir` in the documented layout. gt_meshes, if given,
// holds one posed mesh per frame per video (camera coordinates). The folder is
// written under a temporary name and renamed into place, so a failed write
// leaves nothing half-written. Throws InputError if `dir` exists and is not
// empty, unless overwrite is true.
void WriteDataset(const Dataset& dataset, const std::string& dir,
                  const std::vector<std::vector<TriangleMesh>>* gt_meshes = nullptr,
                  bool overwrite = false);

}  // namespace banmo
