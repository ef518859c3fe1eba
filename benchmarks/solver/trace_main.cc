// banmo_trace: runs the solver on a dataset with a config (plus overrides)
// and records, at checkpoints, time and iteration against loss, Chamfer
// distance and F-scores (banmo protocol) into a CSV. A separate
// benchmark program rather than a `banmo` subcommand: it is measurement
// tooling for the comparisons in benchmarks/solver/, not a user-facing step
// of the pipeline. benchmarks/solver/README.md documents it.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/eval/evaluate.h"
#include "banmo/extract/extract.h"
#include "banmo/geometry/mesh_io.h"
#include "banmo/io/dataset.h"
#include "banmo/optim/config.h"
#include "banmo/optim/load_options.h"
#include "banmo/optim/solver.h"
#include "banmo/registration/root_init.h"
#include "banmo/registration/root_pose_error.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/timer.h"
#include "trace.h"

namespace banmo::bench {
namespace {

// Thrown from on_batch to end a run early (time budget, non-finite values);
// the solver's state unwinds cleanly (RAII) and the model stays readable.
struct StopRun {};

struct EvalFrame {
  int video = 0;
  int frame = 0;
  TriangleMesh gt;
};

struct Options {
  std::string data_dir, config_path, out_dir;
  std::vector<std::string> overrides;
  std::string config_name = "config", scene_name = "scene";
  int every_batches = 0;
  double every_seconds = 0.0;
  int resolution = 64;
  int frame_step = 4;
  int final_resolution = 0;
  double max_solve_seconds = 0.0;
  int threads = -1;
  bool quiet = false;
  bool stop_on_nonfinite = true;
};

void CheckName(const std::string& name, const std::string& flag) {
  if (name.empty() || name.find_first_of(",\"\n") != std::string::npos) {
    ThrowInputError(flag, ": expected a non-empty name without commas or quotes, got '", name, "'");
  }
}

int Run(int argc, char** argv) {
  CLI::App app{
      "Trace a solve: run the stages of a config (with key=value overrides) on a dataset and, "
      "at checkpoints, extract the canonical mesh at a low resolution, articulate a subset of "
      "frames and evaluate them against the ground truth (banmo protocol). Writes OUT/trace.csv "
      "(rewritten atomically at every checkpoint), OUT/config.yaml (resolved) and OUT/done.",
      "banmo_trace"};
  Options o;
  app.add_option("--data", o.data_dir, "Dataset folder with ground-truth meshes")->required();
  app.add_option("--config", o.config_path, "Base stage config (problems/*.yaml)")->required();
  app.add_option("--set", o.overrides,
                 "Override path=value, repeatable (e.g. stages[*].step_rule=lm, "
                 "model.num_bones=4)");
  app.add_option("--out", o.out_dir, "Output folder (trace.csv, config.yaml, done)")->required();
  app.add_option("--config-name", o.config_name, "Name of the configuration in the CSV")
      ->capture_default_str();
  app.add_option("--scene-name", o.scene_name, "Name of the scene in the CSV")
      ->capture_default_str();
  app.add_option("--every-batches", o.every_batches, "Trace every N batches (0 = off)")
      ->capture_default_str();
  app.add_option("--every-seconds", o.every_seconds,
                 "Trace every S seconds of solve time (0 = off)")
      ->capture_default_str();
  app.add_option("--resolution", o.resolution, "Marching-cubes resolution of trace meshes")
      ->capture_default_str();
  app.add_option("--frame-step", o.frame_step, "Evaluate every k-th frame of each video")
      ->capture_default_str();
  app.add_option("--final-resolution", o.final_resolution,
                 "Also evaluate all frames at this resolution at the end (0 = off)")
      ->capture_default_str();
  app.add_option("--max-solve-seconds", o.max_solve_seconds,
                 "Stop the run after this much solve time (0 = run every batch of the config)")
      ->capture_default_str();
  app.add_option("--threads", o.threads, "Worker threads (overrides the config; 0 = all cores)");
  app.add_flag("--quiet", o.quiet, "No solver progress lines");
  CLI11_PARSE(app, argc, argv);

  CheckName(o.config_name, "--config-name");
  CheckName(o.scene_name, "--scene-name");
  if (o.every_batches < 0) ThrowInputError("--every-batches: expected >= 0");
  if (!(o.every_seconds >= 0)) ThrowInputError("--every-seconds: expected >= 0");
  if (o.resolution < 16 || o.resolution > 512) ThrowInputError("--resolution: expected 16..512");
  if (o.final_resolution != 0 && (o.final_resolution < 16 || o.final_resolution > 1024)) {
    ThrowInputError("--final-resolution: expected 0 or 16..1024");
  }
  if (o.frame_step < 1) ThrowInputError("--frame-step: expected >= 1");
  if (!(o.max_solve_seconds >= 0)) ThrowInputError("--max-solve-seconds: expected >= 0");

  Timer wall;
  std::ifstream in(o.config_path);
  if (!in) ThrowInputError(o.config_path, ": cannot read the config");
  std::stringstream text;
  text << in.rdbuf();
  SolverConfig config = ParseConfigWithOverrides(text.str(), o.overrides, o.config_path);
  if (o.threads >= 0) config.threads = o.threads;

  Dataset dataset = LoadDataset(o.data_dir, DatasetLoadOptions(config));
  // The root poses `banmo solve` would start from (registered and smoothed
  // as the config says), so the stability cases with rough poses measure
  // what a user's solve does.
  StdoutLineReporter root_init_reporter("banmo_trace");
  PrepareRootPoseInit(config.model, &dataset, &root_init_reporter);
  std::vector<EvalFrame> eval_frames;
  for (size_t v = 0; v < dataset.videos.size(); ++v) {
    const Video& video = dataset.videos[v];
    if (!video.present.gt_mesh) {
      ThrowInputError(o.data_dir, ": video ", video.name, " has no ground-truth meshes");
    }
    for (size_t t = 0; t < video.frames.size(); t += o.frame_step) {
      if (video.frames[t].skip) continue;
      eval_frames.push_back(
          {static_cast<int>(v), static_cast<int>(t), ReadMesh(video.frames[t].gt_mesh_path)});
    }
  }
  MakeDirectories(o.out_dir);
  WriteFileAtomic(o.out_dir + "/config.yaml", SolverConfigToYaml(config));
  std::remove((o.out_dir + "/done").c_str());
  const std::string csv_path = o.out_dir + "/trace.csv";
  std::string csv = TraceCsvHeader();

  Solver solver(dataset, config, MakeModelForDataset(dataset, config.model));
  double trace_seconds = 0.0;

  // Fills the metrics of `row` from the current model.
  auto evaluate = [&](const Model& model, int resolution, bool all_frames, TraceRow* row) {
    if (const std::optional<RootPoseErrors> e = ComputeRootPoseErrors(model, dataset)) {
      row->root_rot_mean_deg = e->mean_deg;
      row->root_rot_p90_deg = e->p90_deg;
    }
    row->resolution = resolution;
    row->chamfer_cm = std::numeric_limits<double>::quiet_NaN();
    row->fscore[0] = row->fscore[1] = row->fscore[2] = 0.0;
    if (!row->params_finite) return;  // nothing to extract
    ExtractOptions extract;
    extract.grid.resolution = resolution;
    extract.grid.bounds_min = solver.canonical_bounds().min();
    extract.grid.bounds_max = solver.canonical_bounds().max();
    const TriangleMesh canonical = ExtractCanonicalMesh(model, extract);
    row->mesh_vertices = static_cast<int>(canonical.vertices.cols());
    if (canonical.vertices.cols() == 0 || canonical.faces.cols() == 0) return;
    std::vector<TriangleMesh> pred, gt;
    if (all_frames) {
      for (size_t v = 0; v < dataset.videos.size(); ++v) {
        for (size_t t = 0; t < dataset.videos[v].frames.size(); ++t) {
          if (dataset.videos[v].frames[t].skip) continue;
          pred.push_back(MeshInDatasetUnits(model, ArticulateMesh(model, canonical, v, t)));
          gt.push_back(ReadMesh(dataset.videos[v].frames[t].gt_mesh_path));
        }
      }
    } else {
      for (const EvalFrame& f : eval_frames) {
        pred.push_back(
            MeshInDatasetUnits(model, ArticulateMesh(model, canonical, f.video, f.frame)));
        gt.push_back(f.gt);
      }
    }
    try {
      const EvalReport report = EvaluateSequence(pred, gt, EvalOptions{});
      row->eval_frames = static_cast<int>(report.frames.size());
      row->chamfer_cm = report.chamfer_cm;
      for (int k = 0; k < 3; ++k) row->fscore[k] = report.fscore_percent[k];
    } catch (const InputError& e) {
      // E.g. an articulated mesh behind the camera (median depth <= 0): the
      // model is that wrong; recorded as NaN, the run goes on.
      row->fscore[0] = row->fscore[1] = row->fscore[2] = std::numeric_limits<double>::quiet_NaN();
      std::printf("trace: evaluation failed: %s\n", e.what());
    }
  };
  auto write_csv = [&] { WriteFileAtomic(csv_path, csv); };
  auto base_row = [&](const std::string& kind) {
    TraceRow row;
    row.config = o.config_name;
    row.scene = o.scene_name;
    row.kind = kind;
    row.cpu_seconds = ProcessCpuSeconds();
    row.wall_seconds = wall.Seconds();
    row.trace_seconds = trace_seconds;
    return row;
  };

  auto set_progress = [](const BatchProgress& p, TraceRow* row) {
    row->stage = p.stage;
    row->stage_name = p.stage_name;
    row->batch = p.batch;
    row->total_batches = p.total_batches;
    row->solve_seconds = p.solve_seconds;
    row->losses = p.losses;
  };
  // A row of the solver's model as it is now (after `progress` when given),
  // evaluated at `resolution` (every frame when `all_frames`).
  auto model_row = [&](const std::string& kind, const BatchProgress* progress, int resolution,
                       bool all_frames) {
    Timer t;
    TraceRow row = base_row(kind);
    if (progress != nullptr) set_progress(*progress, &row);
    row.nonfinite_what = FirstNonFiniteBlock(solver.model());
    row.params_finite = row.nonfinite_what.empty();
    evaluate(solver.model(), resolution, all_frames, &row);
    trace_seconds += t.Seconds();
    csv += TraceCsvLine(row);
    write_csv();
  };

  model_row("trace", nullptr, o.resolution, false);  // the starting point

  double next_time = o.every_seconds;
  BatchProgress last;
  bool last_traced = true, nonfinite = false, budget_hit = false;
  SolveOptions solve;
  solve.quiet = o.quiet;
  solve.on_batch = [&](const BatchProgress& p, const Model& model) {
    Timer t;
    last = p;
    bool losses_finite = true;
    std::string bad_loss;
    for (const auto& [name, value] : p.losses) {
      if (!std::isfinite(value) && losses_finite) {
        losses_finite = false;
        bad_loss = "loss:" + name;
      }
    }
    const std::string bad_block = FirstNonFiniteBlock(model);
    const bool finite = losses_finite && bad_block.empty();
    const bool at_batches = o.every_batches > 0 && p.total_batches % o.every_batches == 0;
    const bool at_time = o.every_seconds > 0 && p.solve_seconds >= next_time;
    const bool over_budget = o.max_solve_seconds > 0 && p.solve_seconds >= o.max_solve_seconds;
    last_traced = false;
    if (at_batches || at_time || !finite || over_budget) {
      TraceRow row = base_row(finite ? "trace" : "nonfinite");
      set_progress(p, &row);
      row.losses_finite = losses_finite;
      row.params_finite = bad_block.empty();
      row.nonfinite_what = !bad_block.empty() ? bad_block : bad_loss;
      if (finite) evaluate(model, o.resolution, false, &row);
      csv += TraceCsvLine(row);
      write_csv();
      last_traced = true;
      if (!finite) {
        std::printf("trace: NON-FINITE at stage %d (%s) batch %d (total %d): %s\n", p.stage,
                    p.stage_name.c_str(), p.batch, p.total_batches, row.nonfinite_what.c_str());
      }
      while (at_time && next_time <= p.solve_seconds) next_time += o.every_seconds;
    }
    trace_seconds += t.Seconds();
    if (!finite) {
      nonfinite = true;
      throw StopRun{};
    }
    if (over_budget) {
      budget_hit = true;
      throw StopRun{};
    }
  };
  try {
    const SolveResult result = solver.Run(solve);
    (void)result;
  } catch (const StopRun&) {
  }
  // The end of the run.
  if (!last_traced && !nonfinite) model_row("trace", &last, o.resolution, false);
  if (o.final_resolution > 0 && !nonfinite) model_row("final", &last, o.final_resolution, true);
  std::ostringstream done;
  done << "batches " << last.total_batches << "\nsolve_seconds " << last.solve_seconds
       << "\nwall_seconds " << wall.Seconds() << "\ncpu_seconds " << ProcessCpuSeconds()
       << "\ntrace_seconds " << trace_seconds << "\nnonfinite " << (nonfinite ? 1 : 0)
       << "\nbudget_hit " << (budget_hit ? 1 : 0);
  // The final model's sizes (automatic sizing grows them).
  const ModelOptions& sizes = solver.model().options();
  done << "\nnum_bones " << sizes.num_bones << "\nsdf_width " << sizes.field.sdf_width
       << "\ncolor_width " << sizes.field.color_width << "\n";
  WriteFileAtomic(o.out_dir + "/done", done.str());
  std::printf(
      "banmo_trace %s on %s: %d batches, solve %.1f s, wall %.1f s (trace %.1f s), %d bones, "
      "widths %d / %d%s\n",
      o.config_name.c_str(), o.scene_name.c_str(), last.total_batches, last.solve_seconds,
      wall.Seconds(), trace_seconds, sizes.num_bones, sizes.field.sdf_width,
      sizes.field.color_width, nonfinite ? ", NON-FINITE" : "");
  return nonfinite ? 3 : 0;
}

}  // namespace
}  // namespace banmo::bench

int main(int argc, char** argv) {
  try {
    return banmo::bench::Run(argc, argv);
  } catch (const banmo::InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
}
