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

int RunSolve(int argc, char** argv) {
  CLI::App app{
      "Reconstruct an animatable 3D model from a dataset: runs the stages of a config with "
      "Ceres, writes checkpoints, then extracts meshes and (when the dataset has ground truth) "
      "evaluates them.",
      "banmo solve"};
  std::string data_dir, config_path, out_dir, retarget_dir;
  bool resume = false, overwrite = false, no_extract = false, no_eval = false, quiet = false;
  int seed = -1, threads = -1, resolution = 128, stop_after = -1, holdout_every = 0;
  app.add_option("--data", data_dir, "Dataset folder (docs/dataset.md)")->required();
  app.add_option("--config", config_path, "Stage config, e.g. problems/default.yaml")->required();
  app.add_option("--out", out_dir, "Output folder (config.yaml, checkpoint/, meshes/, eval/)")
      ->required();
  app.add_flag("--resume", resume, "Continue from OUT/checkpoint (same result as uninterrupted)");
  app.add_option("--retarget", retarget_dir,
                 "Model folder (OUT/checkpoint of an earlier solve): keep its shape, colour, "
                 "embedding and bones fixed and fit the poses of this dataset's videos");
  app.add_option("--seed", seed,
                 "Random seed (overrides the config's; a --resume continues the checkpoint's)");
  CLI::Option* threads_option =
      app.add_option("--threads", threads, "Worker threads (0 = all cores; overrides the config)");
  app.add_option("--resolution", resolution, "Marching-cubes resolution of the final meshes")
      ->capture_default_str();
  app.add_flag("--overwrite", overwrite, "Allow a non-empty --out (without --resume)");
  app.add_option("--stop-after-batches", stop_after,
                 "Stop once this many batches have run in total, counting those before a "
                 "--resume (checkpoint written, exit status 0; continue with --resume): a long "
                 "solve in pieces");
  app.add_option("--holdout-every", holdout_every,
                 "Leave every N-th frame of each video (frames N/2, N/2 + N, ...) out of every "
                 "loss and score it at the end: mask IoU and PSNR of its rendering with "
                 "transforms interpolated from its neighbours (OUT/holdout/summary.json; 0 = "
                 "none)")
      ->capture_default_str();
  app.add_flag("--no-extract", no_extract, "Skip mesh extraction at the end");
  app.add_flag("--no-eval", no_eval, "Skip evaluation against ground truth at the end");
  app.add_flag("--quiet", quiet, "No progress lines");
  CLI11_PARSE(app, argc, argv);

  SolverConfig config = LoadSolverConfig(config_path);
  if (seed >= 0) config.seed = static_cast<uint32_t>(seed);
  if (threads_option->count() > 0) {
    if (threads < 0) ThrowInputError("--threads: expected >= 0 (0 = all cores), got ", threads);
    config.threads = threads;
  }
  // Retargeting an automatically sized model: its grown sizes come from its
  // checkpoint, and nothing grows (the shared blocks are held constant).
  const bool retarget_auto_sized =
      !retarget_dir.empty() && SwitchOffAutoSizeForRetarget(&config);  // optim/retarget.h
  if (retarget_auto_sized) {
    std::printf(
        "banmo solve: --retarget: model.auto_size switched off; bones and MLP widths "
        "from %s\n",
        retarget_dir.c_str());
  }
  if (resolution < 16 || resolution > 1024) {
    ThrowInputError("--resolution: expected 16..1024, got ", resolution);
  }
  if (app.count("--stop-after-batches") > 0 && stop_after < 0) {
    ThrowInputError("--stop-after-batches: expected an integer >= 0, got ", stop_after);
  }
  namespace fs = std::filesystem;
  std::error_code ec;
  if (resume) {
    if (!fs::exists(out_dir + "/checkpoint/model.yaml") &&
        !fs::exists(out_dir + "/checkpoint.old/model.yaml")) {
      ThrowInputError("--resume: ", out_dir, "/checkpoint does not exist");
    }
    // The random state continues from the checkpoint, so a resumed solve
    // runs with the seed it started with; another --seed would be ignored.
    if (const std::optional<uint32_t> saved = ReadCheckpointSeed(out_dir + "/checkpoint")) {
      if (seed >= 0 && static_cast<uint32_t>(seed) != *saved) {
        ThrowInputError("--seed ", seed, " with --resume: ", out_dir,
                        "/checkpoint continues the random state of seed ", *saved,
                        " (a resumed solve is the uninterrupted one); drop --seed, or solve "
                        "again without --resume");
      }
      config.seed = *saved;
    }
  } else if (fs::exists(out_dir, ec) && !fs::is_empty(out_dir, ec) && !overwrite) {
    ThrowInputError("--out ", out_dir,
                    ": folder exists and is not empty (use --overwrite or --resume)");
  }

  holdout_every =
      ResolveHoldoutEvery(out_dir, resume, app.count("--holdout-every") > 0, holdout_every);
  Timer timer;
  Dataset dataset = LoadDataset(data_dir, DatasetLoadOptions(config));
  std::printf("banmo solve: %zu video(s), %d frame(s) loaded from %s in %.1f s\n",
              dataset.videos.size(), dataset.NumFrames(), data_dir.c_str(), timer.Seconds());
  const HoldoutPlan holdout = MarkHeldOutFrames(holdout_every, &dataset);
  if (holdout.every > 0) {
    std::printf("banmo solve: %zu frame(s) held out (1 in %d of each video; --holdout-every)\n",
                holdout.frames.size(), holdout.every);
  }
  // Registration and smoothing are deterministic, so a resumed solve gets the
  // same tracks (and the same object centre and scene scale from them).
  PrepareRootPoseInit(config.model, &dataset, "banmo solve");
  // Inputs are valid: only now is anything written.
  MakeDirectories(out_dir);
  WriteFileAtomic(out_dir + "/config.yaml", SolverConfigToYaml(config));
  if (holdout.every > 0) {
    WriteFileAtomic(out_dir + "/holdout.yaml", "every: " + std::to_string(holdout.every) + "\n");
  } else if (!resume) {
    std::filesystem::remove(out_dir + "/holdout.yaml", ec);  // an earlier solve's (--overwrite)
  }

  std::unique_ptr<Model> source;
  ModelOptions model_options = config.model;
  if (!retarget_dir.empty()) {
    source = LoadRetargetSource(retarget_dir, retarget_auto_sized, &model_options);
  }
  // The scene scale (docs/solver.md, "Scene scale"), estimated here when
  // auto so that the estimate can be reported.
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
  SolveOptions options;
  options.out_dir = out_dir;
  options.resume = resume;
  options.quiet = quiet;
  options.stop_after_batches = stop_after;
  if (source != nullptr) {
    ApplyRetarget(*source, retarget_dir, model.get(), &options);
    scale_origin = "from the --retarget model";
  }
  if (!resume) {
    std::printf("banmo solve: scene scale s = %.6g (%s); model units = dataset units / s\n",
                model->scene_scale(), scale_origin.c_str());
    const Eigen::Vector3d c = model->canonical_origin() * model->scene_scale();
    if (source == nullptr && model_options.recentre) {
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
  }
  Solver solver(dataset, config, std::move(model));
  // OUT/losses.csv and OUT/stages.csv for banmo report (solve_outputs.h).
  SolveLog log(out_dir, resume);
  options.on_batch = [&log](const BatchProgress& p, const Model&) { log.Add(p); };
  const SolveResult result = solver.Run(options);
  log.Write(result);
  if (result.interrupted) {
    std::printf("%s: resume with  banmo solve --data %s --config %s --out %s --resume\n",
                result.stopped ? "stopped as asked (--stop-after-batches)" : "interrupted",
                data_dir.c_str(), config_path.c_str(), out_dir.c_str());
    return result.stopped ? 0 : 130;
  }
  for (const StageSummary& s : result.stages) {
    if (!s.finite) ThrowInputError("stage ", s.name, " produced non-finite parameters");
  }
  std::printf("banmo solve: %zu stage(s) in %.1f s\n", result.stages.size(), timer.Seconds());
  if (const std::optional<RootPoseErrors> e = ComputeRootPoseErrors(solver.model(), dataset)) {
    const std::optional<RootPoseErrors> body = ComputeBodyPoseErrors(solver.model(), dataset);
    WriteFileAtomic(out_dir + "/root_pose_errors.csv", RootPoseErrorsCsv(*e, &*body));
    std::printf(
        "root poses: rotation error %.2f deg mean, %.2f deg p90, %.2f deg max against the "
        "ground truth (after a global alignment of %.2f deg; %s/root_pose_errors.csv)\n",
        e->mean_deg, e->p90_deg, e->max_deg, e->alignment_deg, out_dir.c_str());
    if (solver.model().num_bones() > 0) {
      std::printf(
          "body poses (root x mean bone rotation): rotation error %.2f deg mean, %.2f deg p90, "
          "%.2f deg max\n",
          body->mean_deg, body->p90_deg, body->max_deg);
    }
  }
  if (holdout.every > 0) InterpolateHeldOutFramesInCheckpoint(holdout, out_dir, &solver.model());
  if (!no_extract) {
    WriteSolveOutputs(solver.model(), dataset, out_dir, resolution, !no_eval);
  }
  if (holdout.every > 0) WriteHoldoutScore(solver.model(), dataset, holdout, out_dir);
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(solve, "Reconstruct an animatable model from a dataset (stage configs)",
                       banmo::RunSolve);
