// banmo render: pictures of a model beside its dataset (input, volume-rendered
// RGB, mask agreement, shaded mesh, mesh by dominant bone) and per-frame error
// maps and mean errors. docs/render.md.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/extract/extract.h"
#include "banmo/io/dataset.h"
#include "banmo/model/model_file.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/enum_names.h"
#include "banmo/util/error.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"
#include "banmo/visualize/sequence.h"
#include "cli_options.h"
#include "command.h"

namespace banmo {
namespace {

std::string Num(double x) {
  if (std::isnan(x)) return "  n/a";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3f", x);
  return buf;
}

// The command line of banmo render.
struct RenderArgs {
  std::string model_dir, data_dir, out_dir, frames_text, bounds_text = "auto", importance = "auto",
                                                         min_sdf_sample = "auto";
  int every = 5, samples = 0, importance_samples = -1, threads = 0, scale = 0;
  bool no_labels = false;
  RenderSequenceOptions options;
};

void AddRenderOptions(CLI::App* app, RenderArgs* a) {
  RenderSequenceOptions& options = a->options;
  app->add_option("--model", a->model_dir, "Model checkpoint folder (written by banmo solve)")
      ->required();
  app->add_option("--data", a->data_dir,
                  "Dataset folder the model was trained on (docs/dataset.md)")
      ->required();
  app->add_option("--out", a->out_dir, "Output folder (created)")->required();
  app->add_option("--frames", a->frames_text,
                  "Frames to render: all, or a comma-separated list of V:T, V:T0-T1, V:* (video "
                  "V, frame T), as banmo extract --frames (default: every --every-th frame)");
  app->add_option("--every", a->every, "Without --frames: frames 0, K, 2K, ... of every video")
      ->capture_default_str();
  app->add_option("--samples", a->samples,
                  "Depth samples per ray (0 = samples_per_ray of the checkpoint's last stage)")
      ->capture_default_str();
  app->add_option("--importance", a->importance,
                  "Importance resampling of the depth samples as the solver's importance_depth: "
                  "auto (as the checkpoint's last stage), on, off")
      ->capture_default_str();
  app->add_option("--importance-samples", a->importance_samples,
                  "Samples the importance pass adds: 0 redraws half of the samples, K > 0 keeps "
                  "them and adds K (-1 = importance_samples of the checkpoint's last stage)")
      ->capture_default_str();
  app->add_option("--min-sdf-sample", a->min_sdf_sample,
                  "One importance sample at each ray's SDF minimum, as the solver's "
                  "min_sdf_sample: auto (as the checkpoint's last stage), on (needs the "
                  "importance pass), off")
      ->capture_default_str();
  // The mean of 4 jittered passes: the expected rendering the losses fit
  // (docs/render.md, "--jitter-passes").
  options.frame.jitter_passes = 4;
  app->add_option("--jitter-passes", options.frame.jitter_passes,
                  "K > 0: the mean of K renderings whose depth samples are jittered within their "
                  "bins as the solver draws them (K times the time); 0: one rendering with the "
                  "samples at the bins' midpoints")
      ->capture_default_str();
  app->add_option("--bounds", a->bounds_text,
                  "Canonical box for the near/far planes and the mesh: 'auto' (the surface's "
                  "bounds + 10 %, as the solver refreshes them) or xmin,ymin,zmin,xmax,ymax,zmax")
      ->capture_default_str();
  app->add_option("--mesh-resolution", options.mesh_resolution,
                  "Marching-cubes cells for the mesh panels (0 = no mesh panels)")
      ->capture_default_str();
  app->add_option("--flow-gap", options.frame.flow_gap,
                  "Flow rendered and compared: frame t -> t + gap (t - gap at the end of a video)")
      ->capture_default_str();
  app->add_option("--rgb-error-max", options.rgb_error_max,
                  "Top of the rgb error colour scale (mean |rendered - input| over channels, "
                  "colours in [0, 1])")
      ->capture_default_str();
  app->add_option("--mask-error-max", options.mask_error_max,
                  "Top of the mask error colour scale (|opacity - mask|)")
      ->capture_default_str();
  app->add_option("--flow-error-max", options.flow_error_max,
                  "Top of the flow error colour scale (endpoint error, pixels)")
      ->capture_default_str();
  app->add_option("--scale", a->scale,
                  "Integer enlargement of the panels (0 = the smallest making them >= 256 px high)")
      ->capture_default_str();
  app->add_flag("--no-labels", a->no_labels, "No text labels on the panels");
  app->add_flag("--video", options.write_video,
                "Also write OUT/sequence.mp4 of the panel images (and OUT/turntable.mp4 with "
                "--turntable) with OpenCV's VideoWriter");
  app->add_option("--fps", options.fps, "Frames per second of the MP4")->capture_default_str();
  app->add_option("--turntable", options.turntable_views,
                  "Also write N views of the canonical mesh turning about its y axis "
                  "(OUT/turntable/view<NNN>.png; 0 = none)")
      ->capture_default_str();
  app->add_option("--chunk", options.frame.chunk_rays, "Rays per batched evaluation (memory bound)")
      ->capture_default_str();
  app->add_option("--threads", a->threads, "Worker threads (0 = all cores)")->capture_default_str();
}

// An auto|on|off option: an error naming `flag` for any other value.
void CheckAutoOnOff(const char* flag, const std::string& value) {
  if (value != "auto" && value != "on" && value != "off") {
    ThrowInputError(flag, ": expected auto, on or off, got '", value, "'");
  }
}

// A checked auto|on|off option resolved against what the model was trained with.
bool AutoOnOff(const std::string& value, bool trained) {
  return value == "on" || (value == "auto" && trained);
}

// Checks the arguments that need neither the model nor the dataset (before OUT
// is created); sets the thread count and explicit --bounds.
void CheckRenderArgs(RenderArgs* a) {
  if (a->threads < 0) ThrowInputError("--threads: expected >= 0, got ", a->threads);
  if (a->threads > 0) SetNumThreads(a->threads);
  if (a->every < 1) ThrowInputError("--every: expected >= 1, got ", a->every);
  if (a->samples < 0) ThrowInputError("--samples: expected >= 0, got ", a->samples);
  if (a->importance_samples < -1) {
    ThrowInputError("--importance-samples: expected -1 (as trained) or >= 0, got ",
                    a->importance_samples);
  }
  if (a->scale < 0) ThrowInputError("--scale: expected >= 0, got ", a->scale);
  if (a->options.frame.jitter_passes < 0) {
    ThrowInputError("--jitter-passes: expected >= 0, got ", a->options.frame.jitter_passes);
  }
  CheckAutoOnOff("--importance", a->importance);
  CheckAutoOnOff("--min-sdf-sample", a->min_sdf_sample);
  if (a->bounds_text != "auto") {
    a->options.frame.canonical_bounds = tools::ParseBoxOption(
        "--bounds", a->bounds_text, "'auto' or 6 numbers xmin,ymin,zmin,xmax,ymax,zmax");
  }
  if (std::filesystem::exists(a->out_dir) && !std::filesystem::is_directory(a->out_dir)) {
    ThrowInputError("--out ", a->out_dir, ": exists and is not a folder");
  }
}

// Sampling as the model was trained (the last stage of its solver config),
// unless --samples / --importance say otherwise.
void SetSampling(const Model& model, const RenderArgs& a, FrameRenderOptions* frame) {
  SetTrainedSampling(model, frame);
  const bool trained_importance = frame->importance;
  const bool trained_min_sdf_sample =
      model.training_sampling() && model.training_sampling()->min_sdf_sample;
  if (a.samples > 0) frame->samples_per_ray = a.samples;
  if (a.importance_samples >= 0) frame->importance_samples = a.importance_samples;
  frame->importance = AutoOnOff(a.importance, trained_importance);
  if (a.min_sdf_sample == "on" && !frame->importance) {
    ThrowInputError(
        "--min-sdf-sample on: needs the importance pass (--importance on, or a model "
        "trained with it)");
  }
  frame->min_sdf_sample = frame->importance && AutoOnOff(a.min_sdf_sample, trained_min_sdf_sample);
}

// The (video, frame) pairs of --frames, or every --every-th frame of every
// video.
std::vector<std::pair<int, int>> SelectFrames(const Model& model, const RenderArgs& a) {
  std::vector<std::pair<int, int>> frames;
  if (a.frames_text.empty()) {
    for (int v = 0; v < model.num_videos(); ++v) {
      for (int t = 0; t < static_cast<int>(model.video(v).frames.size()); t += a.every) {
        frames.emplace_back(v, t);
      }
    }
  } else {
    const FrameSelection selection = ParseFrameSelection(a.frames_text, model, "--frames");
    if (selection.all) {
      for (int v = 0; v < model.num_videos(); ++v) {
        for (int t = 0; t < static_cast<int>(model.video(v).frames.size()); ++t) {
          frames.emplace_back(v, t);
        }
      }
    } else {
      frames = selection.frames;
    }
  }
  if (frames.empty()) ThrowInputError("--frames '", a.frames_text, "': selects no frame");
  return frames;
}

// --scale 0: the smallest integer making the panels >= 256 px high.
int DefaultScale(const Model& model) {
  int height = 1;
  for (int v = 0; v < model.num_videos(); ++v) {
    height = std::max(height, model.video(v).camera.height);
  }
  return std::max(1, (256 + height - 1) / height);
}

void PrintPlan(const std::string& model_dir, const Model& model, size_t num_frames,
               const RenderSequenceOptions& options, bool explicit_bounds) {
  const Eigen::AlignedBox3d& b = options.frame.canonical_bounds;
  std::string importance;
  if (options.frame.importance) {
    importance =
        options.frame.importance_samples > 0
            ? " (+ " + std::to_string(options.frame.importance_samples) + " importance samples"
            : " (+ importance resampling";
    if (options.frame.min_sdf_sample) importance += ", one sample at the SDF minimum";
    importance += ")";
  }
  const std::string jitter =
      options.frame.jitter_passes > 0
          ? ", mean of " + std::to_string(options.frame.jitter_passes) + " jittered passes"
          : "";
  std::printf(
      "model %s: %d videos, %d bones, %s density with beta %.4g; %zu frames to render, %d "
      "samples per ray%s%s, canonical bounds [%.3g %.3g %.3g] - [%.3g %.3g %.3g]%s\n",
      model_dir.c_str(), model.num_videos(), model.num_bones(), EnumName(model.options().density),
      std::exp(*model.log_beta()), num_frames, options.frame.samples_per_ray, importance.c_str(),
      jitter.c_str(), b.min().x(), b.min().y(), b.min().z(), b.max().x(), b.max().y(), b.max().z(),
      explicit_bounds ? "" : " (auto)");
  std::fflush(stdout);
}

void PrintFrameReport(const FrameReport& r, int done, int all) {
  std::printf(
      "  [%d/%d] video %d frame %d: rgb %s  mask %s  IoU %s  flow %s px  (volume %.2f s, "
      "frame %.2f s)\n",
      done, all, r.video, r.frame, Num(r.errors.rgb).c_str(), Num(r.errors.mask).c_str(),
      Num(r.errors.mask_iou).c_str(), Num(r.errors.flow).c_str(), r.volume_seconds,
      r.total_seconds);
  std::fflush(stdout);
}

void PrintSummary(const SequenceSummary& summary, const RenderSequenceOptions& options,
                  const std::string& out_dir, double total_seconds) {
  double volume = 0.0, frame_total = 0.0;
  for (const FrameReport& r : summary.frames) {
    volume += r.volume_seconds;
    frame_total += r.total_seconds;
  }
  const double n = static_cast<double>(summary.frames.size());
  std::printf("mesh panels: %s\n",
              options.mesh_resolution == 0
                  ? "off"
                  : (summary.mesh_vertices > 0
                         ? ("canonical mesh " + std::to_string(summary.mesh_vertices) +
                            " vertices (" + Num(summary.mesh_seconds) + " s)")
                               .c_str()
                         : "the SDF has no zero level set in the bounds: mesh panels are black"));
  if (options.write_video) {
    std::printf("video: %s\n",
                summary.video_path.empty()
                    ? ("not written: " + summary.video_note).c_str()
                    : (summary.video_path + " (" + summary.video_note + ")").c_str());
  }
  if (options.turntable_views > 0) {
    std::printf(
        "turntable: %d views in %s/turntable%s\n", summary.turntable_written, out_dir.c_str(),
        summary.turntable_video_path.empty() ? ""
                                             : (" and " + summary.turntable_video_path).c_str());
  }
  std::printf(
      "wrote %zu frames to %s/frames, error maps to %s/errors, means to %s/errors.csv; "
      "%.2f s per frame (volume rendering %.2f s); total %.1f s\n",
      summary.frames.size(), out_dir.c_str(), out_dir.c_str(), out_dir.c_str(), frame_total / n,
      volume / n, total_seconds);
}

int RunRender(int argc, char** argv) {
  CLI::App app{
      "Render a model beside its dataset (docs/render.md). For each chosen frame, "
      "OUT/frames/video<VV>_frame<TTTTT>.png holds five panels side by side: the input RGB, the "
      "model's RGB by volume rendering (the solver's own ray pipeline), the rendered mask over "
      "the input mask (white both, red rendered only, blue input only, grey unknown), the "
      "articulated mesh (Lambert shading, input camera) and the mesh coloured by dominant bone. "
      "OUT/errors/ holds the rgb, mask and flow error maps (INFERNO colour scale, 0 = black, the "
      "--*-error-max value = pale yellow, grey = undefined) and OUT/errors.csv the per-frame "
      "means. Files of the same names in OUT are replaced; all of them appear at the end (a failed "
      "or killed run leaves none).",
      "banmo render"};
  RenderArgs a;
  AddRenderOptions(&app, &a);
  CLI11_PARSE(app, argc, argv);
  // Everything is validated before OUT is created.
  CheckRenderArgs(&a);
  RenderSequenceOptions& options = a.options;
  const bool explicit_bounds = a.bounds_text != "auto";

  Timer total;
  const std::unique_ptr<Model> model = LoadModel(a.model_dir);
  SetSampling(*model, a, &options.frame);
  LoadOptions load;
  load.load_features = false;
  const Dataset dataset = LoadDataset(a.data_dir, load);
  CheckDatasetMatchesModel(dataset, *model, a.data_dir);
  const std::vector<std::pair<int, int>> frames = SelectFrames(*model, a);
  options.scale = a.scale == 0 ? DefaultScale(*model) : a.scale;
  options.labels = !a.no_labels;
  options.Check();

  if (!explicit_bounds) options.frame.canonical_bounds = CanonicalBoundsFromSurface(*model);
  PrintPlan(a.model_dir, *model, frames.size(), options, explicit_bounds);
  // Everything goes to a staging folder put in place at the end: a failed or
  // killed run leaves no partial set of pictures (docs/robustness.md).
  StagedOutput staged(a.out_dir, "render");
  if (!staged.recovery_note().empty()) {
    std::fprintf(stderr, "banmo render: %s\n", staged.recovery_note().c_str());
  }
  SequenceSummary summary =
      RenderSequence(*model, dataset, frames, options, staged.path(), PrintFrameReport);
  staged.Commit();
  if (!summary.video_path.empty()) summary.video_path = staged.FinalPath(summary.video_path);
  if (!summary.turntable_video_path.empty()) {
    summary.turntable_video_path = staged.FinalPath(summary.turntable_video_path);
  }
  PrintSummary(summary, options, a.out_dir, total.Seconds());
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(render, "Render a model beside its dataset: panels, error maps, mean errors",
                       banmo::RunRender);
