// banmo synth: render a synthetic multi-video dataset from a rig (a built-in
// procedural creature or a skinned, animated glTF file). docs/synth.md.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/io/dataset.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"
#include "banmo/util/enum_names.h"
#include "banmo/util/error.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"
#include "cli_options.h"
#include "command.h"

namespace banmo {
namespace {

std::vector<int> ParseGaps(const std::string& text) {
  std::vector<int> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v < 1 || v > 10000) {
      ThrowInputError("--gaps: '", item, "' is not a positive integer (expected e.g. 1,2,4,8)");
    }
    out.push_back(static_cast<int>(v));
  }
  if (out.empty()) ThrowInputError("--gaps: expected at least one gap");
  return out;
}

// What --realism casual drew per video and did to the masks.
void PrintCasualSummary(const synth::ScenePlan& plan, const synth::SynthScene& scene) {
  std::printf(
      "  realism casual: intrinsics in the manifest are the default assumption; the "
      "true ones are intrinsics_gt, exact masks in mask_gt/, no features, every "
      "root_poses_init the identity\n");
  for (size_t v = 0; v < scene.casual.size(); ++v) {
    const synth::CasualVideo& look = plan.casual[v];
    std::string limbs;
    int holes = 0;
    for (size_t f = 0; f < scene.casual[v].size(); ++f) {
      const synth::CasualFrameRecord& r = scene.casual[v][f];
      holes += r.holes;
      if (r.limb_node >= 0) {
        limbs += (limbs.empty() ? "" : ", ") + std::to_string(f) + " (" +
                 std::to_string(r.limb_pixels) + " px)";
      }
    }
    std::printf(
        "  %s: focal %.3f x size, exposure %.3f, white balance (%.3f, 1, %.3f), ambient %.2f, "
        "sun elevation %.0f deg, noise gain %.2f; %d mask holes, limb missing in frames: %s\n",
        scene.dataset.videos[v].name.c_str(), look.focal_factor, look.exposure,
        look.white_balance[0], look.white_balance[2], look.ambient,
        std::asin(std::clamp(look.light_world.y(), -1.0, 1.0)) * 180 / M_PI, look.noise_gain, holes,
        limbs.empty() ? "none" : limbs.c_str());
  }
}

// --pose-noise-model and --realism into `options`, with the rules between
// them and --pose-noise.
void ResolveSynthModes(const std::string& noise_model, const std::string& realism,
                       synth::SynthOptions* options) {
  const std::optional<synth::PoseNoiseModel> model = ParseEnum<synth::PoseNoiseModel>(noise_model);
  if (!model) {
    ThrowInputError("--pose-noise-model: unknown model '", noise_model, "' (expected one of ",
                    EnumChoices<synth::PoseNoiseModel>(), ")");
  }
  options->pose_noise_model = *model;
  if (options->pose_noise_model == synth::PoseNoiseModel::kGaussian) {
    const synth::GaussianNoisePeak peak = synth::GaussianNoiseMaximum();
    if (!(options->pose_noise_deg <= peak.mean_angle * 180 / M_PI)) {
      ThrowInputError("--pose-noise: ", options->pose_noise_deg,
                      " deg is above the largest mean rotation error the gaussian model reaches, ",
                      std::floor(peak.mean_angle * 180 / M_PI * 100) / 100,
                      " deg (at per-axis sigma ", std::round(peak.sigma * 180 / M_PI * 10) / 10,
                      " deg; a larger sigma wraps more angles past 180 deg and lowers the mean); "
                      "use --pose-noise-model exact for larger errors");
    }
  }
  const std::optional<synth::Realism> realism_mode = ParseEnum<synth::Realism>(realism);
  if (!realism_mode) {
    ThrowInputError("--realism: unknown mode '", realism, "' (expected one of ",
                    EnumChoices<synth::Realism>(), ")");
  }
  options->realism = *realism_mode;
  if (options->realism == synth::Realism::kCasual &&
      (options->pose_noise_deg != 0 ||
       options->pose_noise_model != synth::PoseNoiseModel::kExact)) {
    ThrowInputError(
        "--pose-noise/--pose-noise-model: not used with --realism casual (it writes "
        "no rough root poses: every root_poses_init is the identity at (0, 0, "
        "--distance))");
  }
}

int RunSynth(int argc, char** argv) {
  std::ostringstream rigs;
  for (const auto& n : synth::BuiltinRigNames()) rigs << (rigs.tellp() > 0 ? "|" : "") << n;
  CLI::App app{
      "Render a synthetic multi-video dataset (docs/synth.md, format in docs/dataset.md): the "
      "rig is posed by its animation (linear blend skinning) and rendered along one orbit-arc "
      "camera trajectory per video with partially overlapping coverage; each video plays the "
      "animation from its own offset and speed. Writes RGB, masks, depth, 16-channel features, "
      "forward/backward flow with occlusion for every gap, intrinsics, ground-truth and rough "
      "root poses, and the posed ground-truth mesh per frame (camera coordinates).",
      "banmo synth"};
  synth::SynthOptions options;
  std::string rig_spec = "quadruped";
  std::string out_dir;
  std::string gaps = "1,2,4,8";
  std::string root_offset = "0,0,0";
  bool overwrite = false;
  int threads = 0;
  app.add_option("--rig", rig_spec, "Built-in rig (" + rigs.str() + ") or a .glb/.gltf/.yaml path")
      ->capture_default_str();
  app.add_option("--animation", options.animation,
                 "Animation name (default: the rig's first; Fox.glb has Survey, Walk, Run)");
  app.add_option("--videos", options.num_videos, "Number of videos")->capture_default_str();
  app.add_option("--frames", options.frames_per_video, "Frames per video")->capture_default_str();
  app.add_option("--size", options.image_size, "Image width = height in pixels")
      ->capture_default_str();
  std::string noise_model = EnumName(options.pose_noise_model);
  app.add_option("--pose-noise", options.pose_noise_deg,
                 "Rotation error of the rough root poses in degrees, in [0, 180] (exact) or "
                 "[0, 122.55] (gaussian); see --pose-noise-model")
      ->capture_default_str();
  app.add_option("--pose-noise-model", noise_model,
                 "exact: every frame rotated by exactly --pose-noise degrees about a random axis, "
                 "translation kept. gaussian (BANMo's ablation): rotation vector with i.i.d. "
                 "N(0, sigma^2) components, sigma chosen so that the MEAN rotation error is "
                 "--pose-noise (sigma 12.53 / 31.33 / 56.80 deg for 20 / 50 / 90), and the "
                 "translation reset to "
                 "(0, 0, --distance): object centre on the optical axis at the nominal distance")
      ->capture_default_str();
  app.add_option("--seed", options.seed, "Random seed (cameras, timing, noise)")
      ->capture_default_str();
  app.add_option("--gaps", gaps, "Flow frame gaps, comma separated")->capture_default_str();
  app.add_option("--fps", options.fps, "Frames per second of animation time")
      ->capture_default_str();
  app.add_option("--distance", options.camera_distance, "Camera distance to the object centre")
      ->capture_default_str();
  app.add_option("--focal", options.focal_factor, "Focal length in units of the image size")
      ->capture_default_str();
  app.add_option("--feature-noise", options.feature_noise,
                 "Std of the per-channel feature noise (features are unit vectors)")
      ->capture_default_str();
  app.add_option("--object-scale", options.object_scale,
                 "Scale of the whole scene (object, camera distance, depth, ground truth); "
                 "images are unchanged")
      ->capture_default_str();
  app.add_option("--root-offset", root_offset,
                 "Where the object's centre sits in the root frame, x,y,z in normalised root units "
                 "(half-extent 1): the written root poses change, the images do not. Models rigs "
                 "whose origin is far from the object (glTF origins at the feet)")
      ->capture_default_str();
  std::string realism = EnumName(options.realism);
  app.add_option("--realism", realism,
                 "none: clean renders (black background, exact masks, pixel features, rough root "
                 "poses). casual: what a handheld camera sees (docs/synth.md, \"Realism\"): a "
                 "textured world with the object's shadow, per-video light, exposure, white "
                 "balance and focal length in [0.6, 1.6] x size (the manifest assumes the "
                 "default; the truth is intrinsics_gt), motion blur, sensor noise, JPEG at 85, "
                 "masks degraded like a segmenter's (exact ones in mask_gt/), no features and no "
                 "rough root poses (the truth stays in root_poses_gt.txt)")
      ->capture_default_str();
  app.add_option("--threads", threads, "Worker threads (0 = all cores)")->capture_default_str();
  app.add_option("--out", out_dir, "Output dataset folder (must not exist or be empty)")
      ->required();
  app.add_flag("--overwrite", overwrite, "Replace a non-empty output folder");
  CLI11_PARSE(app, argc, argv);

  options.flow_gaps = ParseGaps(gaps);
  ResolveSynthModes(noise_model, realism, &options);
  options.root_offset = tools::ParseVector3Option("--root-offset", root_offset);
  options.Check();
  if (threads < 0) ThrowInputError("--threads: expected >= 0");
  if (threads > 0) SetNumThreads(threads);
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!overwrite && fs::exists(out_dir, ec) &&
      (!fs::is_directory(out_dir, ec) || !fs::is_empty(out_dir, ec))) {
    ThrowInputError(out_dir, ": exists and is not an empty folder (use --overwrite to replace it)");
  }

  Timer total;
  const synth::Rig rig = synth::LoadRig(rig_spec);
  const synth::ScenePlan plan = synth::PlanScene(rig, options);  // checks the animation name
  std::printf("rig '%s': %d vertices, %d triangles, %zu joints/nodes, animation '%s' (%.2f s)\n",
              rig.name.c_str(), rig.NumVertices(), rig.NumFaces(), rig.nodes.size(),
              plan.animation->name.c_str(), plan.animation->Duration());
  std::fflush(stdout);
  Timer render_timer;
  const synth::SynthScene scene = synth::RenderSyntheticScene(rig, options, [&](int done, int all) {
    std::printf("  rendered video %d/%d (%.1f s)\n", done, all, render_timer.Seconds());
    std::fflush(stdout);
  });
  const double render_seconds = render_timer.Seconds();
  Timer write_timer;
  WriteDataset(scene.dataset, out_dir, &scene.gt_meshes, overwrite);
  const double write_seconds = write_timer.Seconds();
  const std::uintmax_t bytes = DirectoryBytes(out_dir);
  const int frames = scene.dataset.NumFrames();
  std::printf(
      "wrote %s: %d videos x %d frames of %dx%d, flow gaps %s, pose noise %.1f deg (%s), seed "
      "%llu\n"
      "  %.1f MB (%.0f kB per frame); render %.1f s, write %.1f s, total %.1f s\n",
      out_dir.c_str(), options.num_videos, options.frames_per_video, options.image_size,
      options.image_size, gaps.c_str(), options.pose_noise_deg, EnumName(options.pose_noise_model),
      static_cast<unsigned long long>(options.seed), bytes / 1e6, bytes / 1e3 / frames,
      render_seconds, write_seconds, total.Seconds());
  if (options.realism == synth::Realism::kCasual) {
    PrintCasualSummary(plan, scene);
    return 0;
  }
  const synth::PoseNoiseStats noise = synth::MeasurePoseNoise(scene.dataset);
  std::printf(
      "  rough root poses: %s\n"
      "  root_poses_init vs root_poses_gt over %d frames: rotation error mean %.2f deg, p90 %.2f "
      "deg, max %.2f deg; translation error mean %.4g, p90 %.4g\n",
      synth::DescribePoseNoise(options).c_str(), noise.frames, noise.rotation_mean_deg,
      noise.rotation_p90_deg, noise.rotation_max_deg, noise.translation_mean,
      noise.translation_p90);
  if (!options.root_offset.isZero()) {
    std::printf("  object centre at (%g, %g, %g) in the root frame (--root-offset, times %g)\n",
                options.root_offset.x(), options.root_offset.y(), options.root_offset.z(),
                options.object_scale);
  }
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(synth, "Render a synthetic multi-video dataset from a rig", banmo::RunSynth);
