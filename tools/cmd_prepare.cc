// banmo prepare: a real video (or folder of frames) + masks -> the dataset
// format of docs/dataset.md, with DIS optical flow; a new dataset, or one
// more video in an existing dataset (--add).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>
#include <vector>

#include "banmo/io/dataset.h"
#include "banmo/io/prepare.h"
#include "banmo/util/error.h"
#include "banmo/util/timer.h"
#include "cli_options.h"
#include "command.h"

namespace banmo {
namespace {

int RunPrepare(int argc, char** argv) {
  CLI::App app{
      "Prepare a dataset (docs/dataset.md) from a real video: frames from a video file or a "
      "folder of images, one mask per frame, optical flow computed with OpenCV's DIS flow "
      "(forward and backward for every gap) and occlusion from forward-backward consistency.\n"
      "Without --poses, every root pose has the identity rotation (--roots-turn-with-camera: "
      "the camera's rotation since the first frame, from the background's flow), with the "
      "root origin on the ray through the frame's mask centroid "
      "(--roots-on-axis: on the optical axis), at --distance for a mask of the video's median "
      "area and farther for smaller masks (depth ~ 1 / sqrt(area); --roots-at-distance: every "
      "frame at --distance). Without --intrinsics, fx = fy = max(width, height) and the "
      "principal point is the image centre. Without --features, the dataset "
      "has no feature files.\n"
      "Several videos: prepare the first into a new dataset, then each further one with "
      "--add (same --out); the videos already there are not touched.",
      "banmo prepare"};
  PrepareOptions options;
  std::string out_dir;
  std::string gaps = "1,2,4,8";
  std::string intrinsics;
  std::string mask_format = "auto";
  std::string preset = "medium";
  bool overwrite = false;
  bool add = false;
  auto* video = app.add_option("--video", options.video_path, "Input video file (OpenCV)");
  auto* frames =
      app.add_option("--frames", options.frames_dir, "Folder of frame images (sorted by name)");
  video->excludes(frames);
  frames->excludes(video);
  app.add_option("--masks", options.masks_dir,
                 "Folder of mask images: same name stems as the frames (with --video: one per "
                 "frame in sorted order)")
      ->required();
  app.add_option("--out", out_dir,
                 "Output dataset folder (must not exist or be empty; with --add: the existing "
                 "dataset)")
      ->required();
  app.add_option("--gaps", gaps,
                 "Flow frame gaps, comma separated (with --add: default and only choice the "
                 "dataset's gaps)")
      ->capture_default_str();
  app.add_option("--poses", options.poses_path,
                 "Root poses: one 'qw qx qy qz tx ty tz' line per frame (camera_from_root)");
  app.add_option("--intrinsics", intrinsics, "fx,fy,cx,cy in pixels");
  app.add_option("--features", options.features_dir,
                 "Folder of per-frame feature .npy files (H x W x 16, float16/32)");
  app.add_option("--mask-format", mask_format,
                 "auto (BANMo if any value is 128, else binary), binary (0/255 or 0/1; values "
                 ">= 128 are the object) or banmo (128 = object, 255 = ignore)")
      ->capture_default_str();
  app.add_option("--name", options.video_name,
                 "Video folder name in the dataset (default: video_000, or with --add the first "
                 "free one of video_000, video_001, ...)");
  app.add_option("--distance", options.default_distance,
                 "Object distance of the default root poses (scene units): the depth of a frame "
                 "whose mask has the video's median area")
      ->capture_default_str();
  bool on_axis = false;
  app.add_flag("--roots-on-axis", on_axis,
               "Without --poses: put the root origin on the optical axis in every frame instead "
               "of on the ray through the frame's mask centroid");
  bool turn_with_camera = false;
  app.add_flag("--roots-turn-with-camera", turn_with_camera,
               "Without --poses: each root rotation is the camera's rotation since the first "
               "frame (a homography or essential matrix fitted to the background's gap-1 flow) "
               "instead of the identity: for an object that keeps its orientation while the "
               "camera moves round it");
  bool at_distance = false;
  app.add_flag("--roots-at-distance", at_distance,
               "Without --poses: every root origin at depth --distance instead of a depth by "
               "the mask's size (sqrt(median area / area) x --distance, within 3x)");
  options.max_size = 320;
  app.add_option("--max-size", options.max_size,
                 "Working resolution: frames whose longer side exceeds this many pixels are "
                 "scaled down to it before the flow (0 = as read; docs/dataset.md)")
      ->capture_default_str();
  app.add_option("--max-frames", options.max_frames, "Use at most this many frames (0 = all)")
      ->capture_default_str();
  app.add_option("--flow-preset", preset,
                 "DIS preset: medium (OpenCV PRESET_MEDIUM) or fine (medium refined at full "
                 "resolution, slower)")
      ->capture_default_str();
  app.add_option("--fb-alpha", options.flow.fb_alpha,
                 "Forward-backward check: relative tolerance alpha in |f+b|^2 < alpha "
                 "(|f|^2+|b|^2) + beta")
      ->capture_default_str();
  app.add_option("--fb-beta", options.flow.fb_beta,
                 "Forward-backward check: absolute tolerance beta (px^2)")
      ->capture_default_str();
  app.add_flag("--resize-masks", options.resize_masks,
               "Resize masks of another size than their frames (nearest neighbour) instead of "
               "refusing them");
  auto* overwrite_flag =
      app.add_flag("--overwrite", overwrite, "Replace a non-empty output folder");
  app.add_flag("--add", add,
               "Add this video to the existing dataset --out (written beside it, then moved "
               "in; the manifest is replaced last, so a failure leaves the dataset as it was)")
      ->excludes(overwrite_flag);
  CLI11_PARSE(app, argc, argv);
  options.roots_on_mask_centroids = !on_axis;
  options.roots_depth_from_mask_size = !at_distance;
  options.roots_turn_with_camera = turn_with_camera;

  if (options.video_path.empty() && options.frames_dir.empty()) {
    ThrowInputError("banmo prepare: give --video FILE or --frames DIR");
  }
  options.gaps.clear();
  for (double g : tools::ParseNumberList("--gaps", gaps)) {
    if (g != static_cast<int>(g)) ThrowInputError("--gaps: ", g, " is not an integer");
    options.gaps.push_back(static_cast<int>(g));
  }
  if (!intrinsics.empty()) {
    const std::vector<double> k = tools::ParseNumberList("--intrinsics", intrinsics);
    if (k.size() != 4) ThrowInputError("--intrinsics: expected fx,fy,cx,cy (4 numbers)");
    options.intrinsics = Eigen::Vector4d(k[0], k[1], k[2], k[3]);
  }
  if (mask_format == "auto") {
    options.mask_format = MaskFormat::kAuto;
  } else if (mask_format == "binary") {
    options.mask_format = MaskFormat::kBinary;
  } else if (mask_format == "banmo") {
    options.mask_format = MaskFormat::kBanmo;
  } else {
    ThrowInputError("--mask-format: '", mask_format, "', expected auto, binary or banmo");
  }
  if (preset == "medium") {
    options.flow.preset = DisPreset::kMedium;
  } else if (preset == "fine") {
    options.flow.preset = DisPreset::kFine;
  } else {
    ThrowInputError("--flow-preset: '", preset, "', expected medium or fine");
  }
  const bool name_given = app.count("--name") > 0;
  DatasetInfo existing;
  if (add) {
    // Fail before the (slow) flow: the dataset must exist, the name be new.
    existing = ReadDatasetInfo(out_dir);
    if (app.count("--gaps") == 0) options.gaps = existing.flow_gaps;
    if (!name_given) options.video_name = NextVideoName(existing.video_names);
    for (const std::string& name : existing.video_names) {
      if (name == options.video_name) {
        ThrowInputError(out_dir, ": already has a video named '", name,
                        "'; choose another --name (or leave it out for the next free video_NNN)");
      }
    }
  }
  options.Check();

  Timer timer;
  const Dataset dataset = PrepareDataset(options);
  if (add) {
    AddVideosToDataset(dataset, out_dir);
  } else {
    WriteDataset(dataset, out_dir, nullptr, overwrite);
  }
  const Video& v = dataset.videos[0];
  std::printf("%s %s: video '%s', %zu frames of %dx%d, %d skipped (empty mask), in %.1f s\n",
              add ? "added to" : "wrote", out_dir.c_str(), v.name.c_str(), v.frames.size(),
              v.camera.width, v.camera.height, dataset.NumSkippedFrames(), timer.Seconds());
  if (add) {
    std::printf("%s now has %zu videos\n", out_dir.c_str(), existing.video_names.size() + 1);
  }
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(prepare, "Make a dataset from a real video and masks (DIS flow)",
                       banmo::RunPrepare);
