// The in-memory dataset: several unsynchronised videos of one object, with
// masks, optical flow, 16-channel pixel features and rough root poses.
// The on-disk layout is documented in docs/dataset.md; LoadDataset validates
// everything and WriteDataset writes it atomically (temp folder, rename).
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "banmo/geometry/camera.h"
#include "banmo/geometry/mesh.h"
#include "banmo/geometry/se3.h"
#include "banmo/util/enum_names.h"

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

// Whether the kFeatureDim half floats at `feature` (one pixel of
// Frame::features) are a feature: an all-zero vector is none (docs/dataset.md).
// Exact: any nonzero channel counts, however small (features are finite:
// the reader rejects NaN and Inf).
inline bool IsPixelFeature(const cv::float16_t* feature) {
  for (int k = 0; k < kFeatureDim; ++k) {
    if (static_cast<float>(feature[k]) != 0.0f) return true;
  }
  return false;
}

struct Frame {
  int index = 0;     // frame index within its video (0-based)
  cv::Mat rgb;       // CV_8UC3, RGB channel order (not OpenCV's BGR)
  cv::Mat mask;      // CV_8UC1 with values kMaskBackground/Ignore/Object
  cv::Mat features;  // CV_16FC(kFeatureDim) (half floats); zero outside the mask; empty if absent
  std::vector<FlowField> flows;  // one per configured gap and direction present
  cv::Mat depth;                 // CV_32FC1 camera z (scene units), 0 = background; empty if absent
  // Ground-truth mask (CV_8UC1, same values as `mask`) where `mask` is a
  // degraded one (banmo synth --realism casual); empty if absent. Never read
  // by the solver.
  cv::Mat mask_gt;
  Pose root_pose_init = PoseIdentity();  // camera_from_root, rough initialisation G0^t
  std::optional<Pose> root_pose_gt;      // camera_from_root ground truth (synthetic)
  std::string gt_mesh_path;              // posed GT mesh (PLY, camera coords); empty if absent
  bool skip = false;                     // empty mask: warned about and skipped
  // Left out of every loss to be scored afterwards (io/holdout.h); such a
  // frame is also marked skip, so every consumer of the data passes it by.
  bool held_out = false;

  // The flow field for `gap`, or nullptr if absent.
  const FlowField* FlowForGap(int gap) const;
};

// Which optional data a video has on disk (set by LoadDataset from the
// manifest; WriteDataset derives presence from the frames instead).
struct VideoContents {
  bool flow = false;           // forward and backward flow for every gap of Dataset::flow_gaps
  bool features = false;       // features/%05d.npy
  bool depth = false;          // depth/%05d.png (or .npy)
  bool gt_mesh = false;        // gt_mesh/%05d.ply
  bool root_poses_gt = false;  // root_poses_gt.txt
  bool mask_gt = false;        // mask_gt/%05d.png: exact masks (ground truth)
};

struct Video {
  std::string name;
  PinholeCamera camera;
  std::vector<Frame> frames;
  VideoContents present;  // what the files hold (see VideoContents)
  // Written as '#' comment lines (one per line of this text) after the header
  // of root_poses_init.txt, e.g. how `banmo synth` made the rough poses; not
  // read back (LoadDataset leaves it empty).
  std::string root_poses_init_comment;
  // The true intrinsics (fx, fy, cx, cy) when `camera` holds an assumed one
  // (manifest key intrinsics_gt; ground truth, never read by the solver).
  std::optional<Eigen::Vector4d> intrinsics_gt;
};

struct Dataset {
  std::string root;            // folder it was loaded from (empty if in memory)
  std::vector<int> flow_gaps;  // positive gaps; each has forward and backward flow
  std::vector<Video> videos;

  int NumFrames() const;
  // Number of frames marked skip (empty masks).
  int NumSkippedFrames() const;
  // Whether some frame not marked skip has pixel features.
  bool HasPixelFeatures() const;
};

// Format version written to and accepted from manifest.yaml.
inline constexpr int kDatasetFormatVersion = 1;

struct LoadOptions {
  bool load_features = true;  // features are the largest part; skip if unused
  bool load_flow = true;
  bool load_depth = false;    // depth is ground truth, only tests need it
  bool load_mask_gt = false;  // ground-truth masks (mask_gt/), likewise
};

// Loads and validates the dataset in `dir`. Throws InputError naming the file
// and what was expected on any problem (see docs/dataset.md). Frames with an
// empty mask are warned about and marked skip.
Dataset LoadDataset(const std::string& dir, const LoadOptions& options = {});

// Writes `dataset` to `dir` in the documented layout. gt_meshes, if given,
// holds one posed mesh per frame per video (camera coordinates). The folder is
// written under a temporary name and renamed into place, so a failed write
// leaves nothing half-written; what a killed write to the same folder left
// beside it (`<dir>.tmp-<pid>-<n>`, `<dir>.old-<pid>-<n>`) is removed or
// restored first. Throws InputError if `dir` exists and is not empty, unless
// overwrite is true.
void WriteDataset(const Dataset& dataset, const std::string& dir,
                  const std::vector<std::vector<TriangleMesh>>* gt_meshes = nullptr,
                  bool overwrite = false);

// How flow and depth are stored (docs/dataset.md).
enum class FlowEncoding {
  kKittiPng16,  // flow/fw_<g>/%05d.png: 16-bit KITTI encoding, 1/64 px steps, |flow| < 512 px
  kNpy,         // flow/fw_<g>/%05d.npy: float16 H x W x 3 (u, v, valid in {0, 1})
};
enum class DepthEncoding {
  kPng16,  // depth/%05d.png: 16-bit, value * depth_unit = z in scene units, 0 = background
  kNpy,    // depth/%05d.npy: float32 H x W
};

// Their names in the manifest.
template <>
struct EnumNames<FlowEncoding> {
  static constexpr std::pair<FlowEncoding, const char*> kNames[] = {
      {FlowEncoding::kKittiPng16, "kitti_png16"}, {FlowEncoding::kNpy, "npy"}};
};
template <>
struct EnumNames<DepthEncoding> {
  static constexpr std::pair<DepthEncoding, const char*> kNames[] = {
      {DepthEncoding::kPng16, "png16"}, {DepthEncoding::kNpy, "npy"}};
};

struct WriteOptions {
  // Replace a non-empty existing `dir` (the old folder is removed only after
  // the new one is complete).
  bool overwrite = false;
  FlowEncoding flow_encoding = FlowEncoding::kKittiPng16;
  DepthEncoding depth_encoding = DepthEncoding::kPng16;
  // Scene units per count of 16-bit depth; <= 0 picks the finest of
  // {1, 2, 5} x 10^k (k >= -5) that holds the largest depth of the dataset.
  double depth_unit = 0.0;
  // zlib level of the PNGs, 0-9 (OpenCV's IMWRITE_PNG_COMPRESSION).
  int png_compression = 3;

  // Throws InputError naming the field on a bad value.
  void Check() const;
};

// Same as above with explicit options.
void WriteDataset(const Dataset& dataset, const std::string& dir, const WriteOptions& options,
                  const std::vector<std::vector<TriangleMesh>>* gt_meshes = nullptr);

// What a dataset's manifest says about it (validated; frames are not read).
struct DatasetInfo {
  std::vector<int> flow_gaps;            // sorted
  std::vector<std::string> video_names;  // in manifest order
};
// Reads `dir`/manifest.yaml. Throws InputError naming the file and key.
DatasetInfo ReadDatasetInfo(const std::string& dir);

// The first of video_000, video_001, ... (the names `banmo synth` writes) that is
// not in `taken`.
std::string NextVideoName(const std::vector<std::string>& taken);

// Adds the videos of `added` to the existing dataset in `dir` without
// touching the videos already there. `added` must use the dataset's flow
// gaps, and its video names must be new (a clash is an InputError naming the
// video and the dataset). The new videos are written completely into a
// temporary dataset beside `dir` first (WriteDataset), then their folders
// are renamed into `dir` and the manifest is replaced last (atomic rename):
// a failure at any point removes what was added and leaves `dir` as it was.
// The flow and depth encodings of the dataset's manifest are kept
// (`options.flow_encoding`, `depth_encoding` and `depth_unit` are ignored).
void AddVideosToDataset(const Dataset& added, const std::string& dir,
                        const WriteOptions& options = {});

// Total size in bytes of the regular files below `dir` (for summaries).
std::uintmax_t DirectoryBytes(const std::string& dir);

// Path of a frame's file inside a video folder, e.g. FrameFileName(7, "png")
// = "00007.png". Frame indices have five digits (at most 100000 frames).
std::string FrameFileName(int index, const std::string& extension);

// Largest |tx|, |ty|, |tz| of a root pose: far beyond any scene (synth's
// --object-scale 100 puts cameras ~300 away), small enough that no near/far
// plane overflows.
inline constexpr double kMaxPoseTranslation = 1e6;

// Reads a root-pose file: one line per frame, "qw qx qy qz tx ty tz"
// (camera_from_root), '#' starts a comment line. Each quaternion must have
// norm 1 +- 1e-3 (it is then normalised), each translation component at
// most kMaxPoseTranslation. Throws InputError naming the file and line. If
// expected_lines >= 0 the number of pose lines must match.
std::vector<Pose> ReadPoseFile(const std::string& path, int expected_lines = -1);
// Writes poses in the same format (17 significant digits), atomically. Each
// line of `comment` becomes a "# " line after the format header.
void WritePoseFile(const std::string& path, const std::vector<Pose>& poses,
                   const std::string& comment = "");

}  // namespace banmo
