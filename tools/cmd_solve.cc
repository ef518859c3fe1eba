// banmo solve: reconstruct an animatable model from a dataset by running the
// stages of a config (docs/solver.md, docs/config.md).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>

#include "banmo/io/dataset.h"
#include "banmo/model/scene_scale.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/config.h"
#include "banmo/optim/load_options.h"
#include "banmo/optim/retarget.h"
#include "banmo/optim/solver.h"
#include "banmo/registration/root_init.h"
#include "banmo/registration/root_pose_error.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/timer.h"
#include "command.h"
#include "solve_outputs.h"

namespace banmo {
namespace {

// The command line of `banmo solve`.
struct SolveArgs {
  std::string data_dir, config_path, out_dir, retarget_dir;
  bool resume = false, overwrite = false, no_extract = false, no_eval = false, quiet = false;
  int seed = -1, threads = -1, resolution = 128, stop_after = -1, holdout_every = 0;
  CLI::Option* threads_option = nullptr;
};

void AddSolveOptions(CLI::App* app, SolveArgs* a) {
  app->add_option("--data", a->data_dir, "Dataset folder (docs/dataset.md)")->required();
  app->add_option("--config", a->config_path, "Stage config, e.g. problems/default.yaml")
      ->required();
  app->add_option("--out", a->out_dir, "Output folder (config.yaml, checkpoint/, meshes/, eval/)")
      ->required();
  app->add_flag("--resume", a->resume,
                "Continue from OUT/checkpoint (same result as uninterrupted)");
  app->add_option("--retarget", a->retarget_dir,
                  "Model folder (OUT/checkpoint of an earlier solve): keep its shape, colour, "
                  "embedding and bones fixed and fit the poses of this dataset's videos");
  app->add_option("--seed", a->seed,
                  "Random seed (overrides the config's; a --resume continues the checkpoint's)");
  a->threads_option = app->add_option("--threads", a->threads,
                                      "Worker threads (0 = all cores; overrides the config)");
  app->add_option("--resolution", a->resolution, "Marching-cubes resolution of the final meshes")
      ->capture_default_str();
  app->add_flag("--overwrite", a->overwrite, "Allow a non-empty --out (without --resume)");
  app->add_option("--stop-after-batches", a->stop_after,
                  "Stop once this many batches have run in total, counting those before a "
                  "--resume (checkpoint written, exit status 0; continue with --resume): a long "
                  "solve in pieces");
  app->add_option("--holdout-every", a->holdout_every,
                  "Leave every N-th frame of each video (frames N/2, N/2 + N, ...) out of every "
                  "loss and score it at the end: mask IoU and PSNR of its rendering with "
                  "transforms interpolated from its neighbours (OUT/holdout/summary.json; 0 = "
                  "none)")
      ->capture_default_str();
  app->add_flag("--no-extract", a->no_extract, "Skip mesh extraction at the end");
  app->add_flag("--no-eval", a->no_eval, "Skip evaluation against ground truth at the end");
  app->add_flag("--quiet", a->quiet, "No progress lines");
}

// A solve killed before its first checkpoint left OUT with config.yaml (and
// perhaps holdout.yaml or a partial checkpoint.tmp) and nothing to resume:
// --resume then starts it again from the beginning, which is what the
// uninterrupted solve did, with the seed and --holdout-every it recorded
// (unless given again). Changes `a` into the arguments of that fresh solve.
void RestartIfNoCheckpointYet(const CLI::App& app, SolveArgs* a) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const std::string& out = a->out_dir;
  if (!a->resume || fs::exists(out + "/checkpoint/model.yaml", ec) ||
      fs::exists(out + "/checkpoint.old/model.yaml", ec) ||
      !fs::is_regular_file(out + "/config.yaml", ec)) {
    return;
  }
  if (a->seed < 0) a->seed = static_cast<int>(LoadSolverConfig(out + "/config.yaml").seed);
  a->holdout_every =
      ResolveHoldoutEvery(out, true, app.count("--holdout-every") > 0, a->holdout_every);
  std::printf(
      "banmo solve: %s has no checkpoint yet (the solve stopped before its first): starting "
      "it again from the beginning (seed %d)\n",
      out.c_str(), a->seed);
  a->resume = false;
  a->overwrite = true;
}

// The config with the command line's overrides; checks the arguments and
// the output folder (InputError naming the option). *retarget_auto_sized:
// automatic sizing was switched off for --retarget.
SolverConfig ResolveSolveConfig(const CLI::App& app, const SolveArgs& a,
                                bool* retarget_auto_sized) {
  SolverConfig config = LoadSolverConfig(a.config_path);
  if (a.seed >= 0) config.seed = static_cast<uint32_t>(a.seed);
  if (a.threads_option->count() > 0) {
    if (a.threads < 0) ThrowInputError("--threads: expected >= 0 (0 = all cores), got ", a.threads);
    config.threads = a.threads;
  }
  // Retargeting an automatically sized model: its grown sizes come from its
  // checkpoint, and nothing grows (the shared blocks are held constant).
  *retarget_auto_sized =
      !a.retarget_dir.empty() && SwitchOffAutoSizeForRetarget(&config);  // optim/retarget.h
  if (*retarget_auto_sized) {
    std::printf(
        "banmo solve: --retarget: model.auto_size switched off; bones and MLP widths "
        "from %s\n",
        a.retarget_dir.c_str());
  }
  if (a.resolution < 16 || a.resolution > 1024) {
    ThrowInputError("--resolution: expected 16..1024, got ", a.resolution);
  }
  if (app.count("--stop-after-batches") > 0 && a.stop_after < 0) {
    ThrowInputError("--stop-after-batches: expected an integer >= 0, got ", a.stop_after);
  }
  namespace fs = std::filesystem;
  std::error_code ec;
  if (a.resume) {
    if (!fs::exists(a.out_dir + "/checkpoint/model.yaml") &&
        !fs::exists(a.out_dir + "/checkpoint.old/model.yaml")) {
      ThrowInputError("--resume: ", a.out_dir, "/checkpoint does not exist");
    }
    // The random state continues from the checkpoint, so a resumed solve
    // runs with the seed it started with; another --seed would be ignored.
    if (const std::optional<uint32_t> saved = ReadCheckpointSeed(a.out_dir + "/checkpoint")) {
      if (a.seed >= 0 && static_cast<uint32_t>(a.seed) != *saved) {
        ThrowInputError("--seed ", a.seed, " with --resume: ", a.out_dir,
                        "/checkpoint continues the random state of seed ", *saved,
                        " (a resumed solve is the uninterrupted one); drop --seed, or solve "
                        "again without --resume");
      }
      config.seed = *saved;
    }
  } else if (fs::exists(a.out_dir, ec) && !fs::is_empty(a.out_dir, ec) && !a.overwrite) {
    ThrowInputError("--out ", a.out_dir,
                    ": folder exists and is not empty (use --overwrite or --resume)");
  }
  return config;
}

// Prints the scene scale and the canonical origin of a new solve's model.
void PrintModelFrame(const Model& model, const std::string& scale_origin, bool recentred,
                     const ObjectCentreEstimate& centre) {
  std::printf("banmo solve: scene scale s = %.6g (%s); model units = dataset units / s\n",
              model.scene_scale(), scale_origin.c_str());
  const Eigen::Vector3d c = model.canonical_origin() * model.scene_scale();
  if (!recentred) return;
  if (centre.triangulated) {
    std::printf(
        "banmo solve: canonical origin at the object centre (%.4g, %.4g, %.4g) of the root "
        "frame, triangulated from %d mask(s) (model.recentre)\n",
        c.x(), c.y(), c.z(), centre.frames_used);
  } else {
    std::printf(
        "banmo solve: canonical origin at the root origin: the cameras of the root poses do "
        "not move enough to triangulate the object (model.recentre)\n");
  }
}

// The model for the dataset: with --retarget the source's shared blocks held
// constant (options->extra_constant); the scene scale estimated here when
// auto so that the estimate can be reported (docs/solver.md, "Scene scale").
std::unique_ptr<Model> MakeSolveModel(const SolverConfig& config, const Dataset& dataset,
                                      const SolveArgs& a, bool retarget_auto_sized,
                                      SolveOptions* options) {
  std::unique_ptr<Model> source;
  ModelOptions model_options = config.model;
  if (!a.retarget_dir.empty()) {
    source = LoadRetargetSource(a.retarget_dir, retarget_auto_sized, &model_options);
  }
  std::string scale_origin = "model.scene_scale";
  const ObjectCentreEstimate centre = EstimateObjectCentre(dataset);
  if (!model_options.scene_scale) {
    const SceneScaleEstimate e = EstimateSceneScale(
        dataset, model_options.recentre ? centre.centre : Eigen::Vector3d::Zero());
    model_options.scene_scale = e.scale;
    char text[160];
    std::snprintf(text, sizeof(text), "auto: estimate %.4g from %d frame(s)%s", e.estimate,
                  e.frames_used, e.border_used ? ", all touching the image border" : "");
    scale_origin = text;
  }
  std::unique_ptr<Model> model = MakeModelForDataset(dataset, model_options);
  if (source != nullptr) {
    ApplyRetarget(*source, a.retarget_dir, model.get(), options);
    scale_origin = "from the --retarget model";
  }
  if (!a.resume) {
    PrintModelFrame(*model, scale_origin, source == nullptr && model_options.recentre, centre);
  }
  return model;
}

// OUT/root_pose_errors.csv and its summary, when the dataset has
// ground-truth poses.
void ReportRootPoseErrors(const Model& model, const Dataset& dataset, const std::string& out_dir) {
  const std::optional<RootPoseErrors> e = ComputeRootPoseErrors(model, dataset);
  if (!e) return;
  const std::optional<RootPoseErrors> body = ComputeBodyPoseErrors(model, dataset);
  WriteFileAtomic(out_dir + "/root_pose_errors.csv", RootPoseErrorsCsv(*e, &*body));
  std::printf(
      "root poses: rotation error %.2f deg mean, %.2f deg p90, %.2f deg max against the "
      "ground truth (after a global alignment of %.2f deg; %s/root_pose_errors.csv)\n",
      e->mean_deg, e->p90_deg, e->max_deg, e->alignment_deg, out_dir.c_str());
  if (model.num_bones() > 0) {
    std::printf(
        "body poses (root x mean bone rotation): rotation error %.2f deg mean, %.2f deg p90, "
        "%.2f deg max\n",
        body->mean_deg, body->p90_deg, body->max_deg);
  }
}

int RunSolve(int argc, char** argv) {
  CLI::App app{
      "Reconstruct an animatable 3D model from a dataset: runs the stages of a config with "
      "Ceres, writes checkpoints, then extracts meshes and (when the dataset has ground truth) "
      "evaluates them.",
      "banmo solve"};
  SolveArgs a;
  AddSolveOptions(&app, &a);
  CLI11_PARSE(app, argc, argv);
  RestartIfNoCheckpointYet(app, &a);
  bool retarget_auto_sized = false;
  const SolverConfig config = ResolveSolveConfig(app, a, &retarget_auto_sized);
  const std::string& out_dir = a.out_dir;
  const int holdout_every =
      ResolveHoldoutEvery(out_dir, a.resume, app.count("--holdout-every") > 0, a.holdout_every);
  Timer timer;
  Dataset dataset = LoadDataset(a.data_dir, DatasetLoadOptions(config));
  std::printf("banmo solve: %zu video(s), %d frame(s) loaded from %s in %.1f s\n",
              dataset.videos.size(), dataset.NumFrames(), a.data_dir.c_str(), timer.Seconds());
  const HoldoutPlan holdout = MarkHeldOutFrames(holdout_every, &dataset);
  if (holdout.every > 0) {
    std::printf("banmo solve: %zu frame(s) held out (1 in %d of each video; --holdout-every)\n",
                holdout.frames.size(), holdout.every);
  }
  // Registration and smoothing are deterministic, so a resumed solve gets the
  // same tracks (and the same object centre and scene scale from them).
  StdoutLineReporter root_init_reporter("banmo solve");
  PrepareRootPoseInit(config.model, &dataset, &root_init_reporter);
  // Inputs are valid: only now is anything written.
  MakeDirectories(out_dir);
  WriteFileAtomic(out_dir + "/config.yaml", SolverConfigToYaml(config));
  std::error_code ec;
  if (holdout.every > 0) {
    WriteFileAtomic(out_dir + "/holdout.yaml", "every: " + std::to_string(holdout.every) + "\n");
  } else if (!a.resume) {
    std::filesystem::remove(out_dir + "/holdout.yaml", ec);  // an earlier solve's (--overwrite)
  }

  SolveOptions options;
  options.out_dir = out_dir;
  options.resume = a.resume;
  options.quiet = a.quiet;
  options.stop_after_batches = a.stop_after;
  std::unique_ptr<Model> model = MakeSolveModel(config, dataset, a, retarget_auto_sized, &options);
  Solver solver(dataset, config, std::move(model));
  // OUT/losses.csv and OUT/stages.csv for banmo report (solve_outputs.h).
  SolveLog log(out_dir, a.resume);
  options.on_batch = [&log](const BatchProgress& p, const Model&) { log.Add(p); };
  const SolveResult result = solver.Run(options);
  log.Write(result);
  if (result.interrupted) {
    std::printf("%s: resume with  banmo solve --data %s --config %s --out %s --resume\n",
                result.stopped ? "stopped as asked (--stop-after-batches)" : "interrupted",
                a.data_dir.c_str(), a.config_path.c_str(), out_dir.c_str());
    return result.stopped ? 0 : 130;
  }
  for (const StageSummary& s : result.stages) {
    if (!s.finite) ThrowInputError("stage ", s.name, " produced non-finite parameters");
  }
  std::printf("banmo solve: %zu stage(s) in %.1f s\n", result.stages.size(), timer.Seconds());
  ReportRootPoseErrors(solver.model(), dataset, out_dir);
  if (holdout.every > 0) InterpolateHeldOutFramesInCheckpoint(holdout, out_dir, &solver.model());
  if (!a.no_extract) WriteSolveOutputs(solver.model(), dataset, out_dir, a.resolution, !a.no_eval);
  if (holdout.every > 0) WriteHoldoutScore(solver.model(), dataset, holdout, out_dir);
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(solve, "Reconstruct an animatable model from a dataset (stage configs)",
                       banmo::RunSolve);
