// banmo check DIR: validate a dataset (docs/dataset.md) and print a summary.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "banmo/geometry/se3.h"
#include "banmo/io/dataset.h"
#include "banmo/model/scene_scale.h"
#include "banmo/util/timer.h"
#include "command.h"

namespace banmo {
namespace {

std::string HumanBytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024 && u < 4) {
    bytes /= 1024;
    ++u;
  }
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), u == 0 ? "%.0f %s" : "%.2f %s", bytes, units[u]);
  return buffer;
}

// What the solver would miss (docs/dataset.md, "What the solver needs that
// real data may lack"): not errors, the dataset is valid without them.
void PrintNotes(const Dataset& dataset) {
  for (const Video& v : dataset.videos) {
    if (!v.present.features) {
      std::printf(
          "note: video %s has no pixel features: the feature_match, cycle_2d and "
          "feature_render losses get no residuals there\n",
          v.name.c_str());
    }
    bool all_same = v.frames.size() > 1;
    for (const Frame& f : v.frames) {
      all_same =
          all_same && f.root_pose_init.head<kPoseT>() == v.frames[0].root_pose_init.head<kPoseT>();
    }
    if (all_same) {
      std::printf(
          "note: video %s: every initial root pose has the same rotation (banmo prepare "
          "without --poses?): the solver starts every frame from it, unless "
          "model.root_init_registration registers the frames from their features%s\n",
          v.name.c_str(), v.present.features ? "" : " (this video has none)");
    }
  }
}

int RunCheck(int argc, char** argv) {
  CLI::App app{
      "Validate a dataset folder (manifest, every image, flow, feature and pose file; "
      "docs/dataset.md) and print a summary. Exit status 0 if valid, 2 with the error naming "
      "the file otherwise. Frames with an empty mask are reported as skipped (a warning, not an "
      "error).",
      "banmo check"};
  std::string dir;
  bool quick = false;
  app.add_option("DIR", dir, "Dataset folder (holds manifest.yaml)")->required();
  app.add_flag("--quick", quick,
               "Check files and headers of features, flow and depth without decoding them "
               "(faster; NaN/Inf in .npy data is then not detected)");
  CLI11_PARSE(app, argc, argv);

  Timer timer;
  LoadOptions options;
  options.load_features = !quick;
  options.load_flow = !quick;
  options.load_depth = !quick;
  options.load_mask_gt = !quick;
  const Dataset dataset = LoadDataset(dir, options);
  const double seconds = timer.Seconds();
  const std::uintmax_t bytes = DirectoryBytes(dataset.root);
  const int frames = dataset.NumFrames();

  std::printf("dataset   %s\n", dataset.root.c_str());
  std::printf("videos    %zu\n", dataset.videos.size());
  std::printf("frames    %d (%d skipped: empty mask)\n", frames, dataset.NumSkippedFrames());
  std::string gaps;
  for (int g : dataset.flow_gaps) gaps += (gaps.empty() ? "" : ", ") + std::to_string(g);
  std::printf("flow gaps %s\n", gaps.empty() ? "none" : gaps.c_str());
  // What `banmo solve` takes as its canonical origin and scene scale with
  // model.recentre: true and model.scene_scale: auto (the defaults).
  const ObjectCentreEstimate centre = EstimateObjectCentre(dataset);
  const SceneScaleEstimate scale = EstimateSceneScale(dataset, centre.centre);
  const std::string centre_origin =
      centre.triangulated
          ? "object centre from " + std::to_string(centre.frames_used) + " mask(s)"
          : std::string("the root origin: the cameras do not move enough to triangulate");
  std::printf("centre    (%.4g, %.4g, %.4g) in the root frame (%s)\n", centre.centre.x(),
              centre.centre.y(), centre.centre.z(), centre_origin.c_str());
  std::printf("scale     s = %.6g (estimate %.4g from %d frame(s)%s; docs/solver.md)\n",
              scale.scale, scale.estimate, scale.frames_used,
              scale.border_used ? ", all touching the image border" : "");
  std::printf("on disk   %s (%s per frame)\n", HumanBytes(static_cast<double>(bytes)).c_str(),
              HumanBytes(frames > 0 ? static_cast<double>(bytes) / frames : 0.0).c_str());
  for (const Video& v : dataset.videos) {
    std::string present = "rgb mask root_poses_init";
    if (v.present.flow) present += " flow";
    if (v.present.features) present += " features";
    if (v.present.depth) present += " depth";
    if (v.present.gt_mesh) present += " gt_mesh";
    if (v.present.root_poses_gt) present += " root_poses_gt";
    if (v.present.mask_gt) present += " mask_gt";
    std::string skipped;
    for (const Frame& f : v.frames) {
      if (f.skip) skipped += (skipped.empty() ? "" : ",") + std::to_string(f.index);
    }
    const auto& k = v.camera.intrinsics;
    std::printf("video %s: %zu frames, %dx%d, intrinsics fx %.6g fy %.6g cx %.6g cy %.6g\n",
                v.name.c_str(), v.frames.size(), v.camera.width, v.camera.height, k[0], k[1], k[2],
                k[3]);
    if (v.intrinsics_gt) {
      const auto& g = *v.intrinsics_gt;
      std::printf("  true intrinsics (ground truth): fx %.6g fy %.6g cx %.6g cy %.6g\n", g[0], g[1],
                  g[2], g[3]);
    }
    std::printf("  present: %s\n", present.c_str());
    std::printf("  skipped frames: %s\n", skipped.empty() ? "none" : skipped.c_str());
  }
  PrintNotes(dataset);
  std::printf("valid (%s check in %.2f s)\n", quick ? "quick" : "full", seconds);
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(check, "Validate a dataset folder and print a summary", banmo::RunCheck);
