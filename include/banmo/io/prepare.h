// Dataset preparation from a real video (`banmo prepare`): frames + user
// masks -> the dataset format of docs/dataset.md, with DIS optical flow and
// forward-backward occlusion, optional features and root poses.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "banmo/io/camera_motion.h"
#include "banmo/io/dataset.h"
#include "banmo/io/optical_flow.h"

namespace banmo {

// How mask PNG values are read.
enum class MaskFormat {
  kAuto,    // kBanmo if any value is 128, else kBinary; other values are an error
  kBinary,  // 0/255 or 0/1: object = value >= 128 (or == 1 if every mask is 0/1)
  kBanmo,   // BANMo's format: 0 = background, 128 = object, 255 = ignore
};

struct PrepareOptions {
  std::string video_path;    // a video file read with cv::VideoCapture, or ...
  std::string frames_dir;    // ... a folder of images (.png .jpg .jpeg .bmp), sorted by name
  std::string masks_dir;     // one mask image per frame (same stems as the frames; in video
                             // mode the sorted masks are matched to frames in order)
  std::string features_dir;  // optional: one .npy (H x W x 16, float16/32) per frame, same rule
  std::string poses_path;    // optional: root poses, one "qw qx qy qz tx ty tz" line per frame
  std::string video_name = "video_000";       // folder name of the video in the dataset
  std::vector<int> gaps = {1, 2, 4, 8};       // flow frame gaps (positive, unique)
  std::optional<Eigen::Vector4d> intrinsics;  // fx, fy, cx, cy; default: max(w, h), centre
  MaskFormat mask_format = MaskFormat::kAuto;
  // Masks of another size than their frames: false = error naming both
  // sizes, true = resized to the frame size (nearest neighbour).
  bool resize_masks = false;
  // Without a poses file: identity rotation, the root origin this far
  // along +z (scene units) ...
  double default_distance = 3.0;
  // ... and on the ray through the frame's mask centroid (true), so a
  // subject that crosses the frame starts where its mask is: the silhouette
  // term has little gradient for a rendered object that does not overlap
  // its mask. false: on the optical axis in every frame.
  bool roots_on_mask_centroids = true;
  // ... at a depth by the mask's size (true): `default_distance` for a frame
  // whose mask has the video's median area, farther for smaller masks
  // (PlaceRootsOnMaskCentroids). false: every frame at `default_distance`.
  bool roots_depth_from_mask_size = true;
  // ... and turned with the camera (true): each frame's root rotation is the
  // camera's rotation since frame 0, estimated from the background's flow
  // (EstimateCameraRotations), for an object that keeps its orientation in
  // the world while the camera moves round it. false: identity rotations,
  // for a subject the camera follows (it keeps facing the camera the same
  // way). Needs flow gap 1. Off by default: on DAVIS libby, parkour and
  // goat and on the five-video casual scene it did not help
  // (docs/dataset.md).
  bool roots_turn_with_camera = false;
  CameraRotationOptions camera_rotation;
  int max_frames = 0;  // use at most this many frames from the start (0 = all)
  // Working resolution: frames whose longer side exceeds this many pixels
  // are scaled down to it (colour by area averaging, masks by a vote of the
  // area, features by area averaging; given intrinsics are scaled alike)
  // before the flow is computed; 0 keeps the size read. The solver samples
  // rays, so its cost does not grow with pixels, while flow time, memory and
  // rendering do (docs/dataset.md, "Working resolution").
  int max_size = 0;
  OpticalFlowOptions flow;

  // Throws InputError naming the option on a bad value or missing path.
  void Check() const;
};

// Reads everything, computes flow and returns the in-memory dataset (one
// video). Throws InputError naming the file on any bad input: unreadable
// files, frames of different sizes (names the first offending file), masks
// of another size than their frames (names both sizes), fewer than 2 frames
// with a non-empty mask.
Dataset PrepareDataset(const PrepareOptions& options);

// Places the root origin of every frame of `video` (masks and intrinsics
// set) on the ray through its mask centroid (pixel centres x + 0.5) at depth
// z_t, keeping the rotation: t = z_t (K^-1 (u, v, 1)). z_t = `distance`, or
// with `depth_from_size` distance * sqrt(A / A_t), A_t the frame's object
// pixels and A their median over the video's frames (the upper middle value
// for an even count), clamped to
// [distance / kMaxRootDepthRatio, distance * kMaxRootDepthRatio]: an object's
// image shrinks as 1 / depth, so a subject walking away starts farther away
// rather than at one depth the solver must move it from. Frames without object
// pixels take the nearest frame's translation (the earlier one on a tie).
inline constexpr double kMaxRootDepthRatio = 3.0;
void PlaceRootsOnMaskCentroids(double distance, bool depth_from_size, Video* video);

// Converts one mask image (CV_8UC1) to kMaskBackground/Ignore/Object.
// `binary_01` selects the 0/1 reading of kBinary. Throws InputError naming
// `name` on values the format does not allow.
cv::Mat ConvertMask(const cv::Mat& raw, MaskFormat format, bool binary_01, const std::string& name);

}  // namespace banmo
