#include "banmo/optim/solver.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>

#include "banmo/deform/bone_centres.h"
#include "banmo/extract/extract.h"
#include "banmo/extract/skeleton.h"
#include "banmo/geometry/pose_manifold.h"
#include "banmo/losses/ray_batch.h"
#include "banmo/losses/regularizers.h"
#include "banmo/optim/auto_size.h"
#include "banmo/optim/bounds_refresh.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/pose_solve.h"
#include "banmo/optim/ray_sampler.h"
#include "banmo/optim/solve_reporter.h"
#include "banmo/registration/bone_registration.h"
#include "banmo/registration/root_pose_error.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"
#include "banmo/volume/ray_samples.h"
#include "divergence_guard.h"
#include "solver_state.h"
#include "stage_problem.h"
#include "step_rules.h"

namespace banmo {
namespace {

std::atomic<bool> g_interrupted{false};

// n points drawn uniformly in `bounds` (the soft-argmax's canonical grid).
Eigen::Matrix3Xd UniformPoints(const Eigen::AlignedBox3d& bounds, int n, std::mt19937* rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::Matrix3Xd points(3, n);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) points(k, i) = bounds.min()[k] + unit(*rng) * bounds.sizes()[k];
  }
  return points;
}
void OnSigint(int) { g_interrupted = true; }

// Installs the SIGINT handler for the lifetime of a run.
class SigintGuard {
 public:
  SigintGuard() {
    g_interrupted = false;
    previous_ = std::signal(SIGINT, OnSigint);
  }
  ~SigintGuard() { std::signal(SIGINT, previous_); }

 private:
  void (*previous_)(int);
};

}  // namespace

Solver::Solver(const Dataset& dataset, const SolverConfig& config, std::unique_ptr<Model> model)
    : dataset_(dataset), config_(config), model_(std::move(model)) {
  CHECK(model_ != nullptr);
  // GT is normalised to a largest half-extent of 1 (docs/dataset.md); the
  // bounds start a little larger and are refreshed from the surface.
  bounds_ = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1.2), Eigen::Vector3d::Constant(1.2));
}

Solver::~Solver() = default;

SolveResult Solver::Run(const SolveOptions& options) {
  SolverState state;
  state.rng.seed(config_.seed);
  state.bounds = bounds_;
  if (options.resume) {
    CHECK(!options.out_dir.empty());
    CheckpointInfo info;
    std::string bytes;
    model_ = LoadCheckpoint(options.out_dir + "/checkpoint", &info, &bytes);
    if (bytes.empty()) ThrowInputError(options.out_dir, "/checkpoint: no solver state to resume");
    state.Deserialize(bytes);
    bounds_ = state.bounds;
    // stage == number of stages: every stage done (the final checkpoint).
    const int stages = static_cast<int>(config_.stages.size());
    for (const auto& [stage, batch] :
         {std::pair(info.stage, info.batch), std::pair(state.stage, state.batch)}) {
      if (stage < 0 || stage > stages || batch < 0 ||
          (stage < stages && batch >= config_.stages[stage].batches) ||
          (stage == stages && batch != 0)) {
        ThrowInputError(options.out_dir, "/checkpoint: stage ", stage, ", batch ", batch,
                        " is out of range for the config's ", stages,
                        " stage(s) (checkpoint.yaml or state.bin is damaged, or from another "
                        "config)");
      }
    }
  }
  internal::CheckFlowGaps(config_, dataset_);
  // The model records how it is trained (saved with it, model/model_file.h).
  if (!config_.stages.empty()) {
    const StageConfig& last = config_.stages.back();
    model_->set_training_sampling(TrainingSampling{
        last.samples_per_ray, last.sampling.near_far_margin, last.sampling.importance_depth,
        last.sampling.clip_to_box, last.sampling.clip_margin, last.sampling.importance_samples,
        last.sampling.min_sdf_sample});
  }
  SigintGuard guard;
  if (config_.threads > 0) SetNumThreads(config_.threads);
  SolveResult result = RunStages(options, &state);
  model_->set_canonical_bounds(bounds_);
  return result;
}

// Everything one Run shares across its stages.
struct Solver::RunContext {
  RunContext(const Dataset& dataset, const SolveOptions& options, SolverState* state)
      : options(options), state(state), sampler(dataset) {
    sampler.set_error_cache(state->error_cache);
    reporter = options.reporter != nullptr ? options.reporter : &printing_reporter;
  }
  // Progress lines and events unless options.quiet; warnings always.
  bool Says(SolveMessageKind kind) const {
    return kind == SolveMessageKind::kWarning || !options.quiet;
  }
  void Say(SolveMessageKind kind, const StageConfig& stage, int batch, std::string text) {
    if (Says(kind)) reporter->Report(SolveMessage{kind, stage.name, batch, std::move(text)});
  }
  const SolveOptions& options;
  SolverState* state;
  PrintingReporter printing_reporter;
  SolveReporter* reporter = nullptr;  // options.reporter, else printing_reporter
  RaySampler sampler;
  std::map<const double*, std::string> block_names;  // Model::ForEachBlock
  std::string resolved_config;
  ParameterGroupSet extra_constant;
  Timer run_timer;
  double callback_seconds = 0.0;  // time inside options.on_batch (excluded from timings)
  // The divergence guard's last good state: the checkpoint on disk once one
  // is written (or resumed from), else the run's start, kept in memory.
  bool checkpoint_written = false;
  std::vector<double> start_parameters;
  SolverState start_state;
  Eigen::AlignedBox3d start_bounds;
};

// One stage's progress, for the progress lines and the summary.
struct Solver::StageRun {
  int index = 0;
  const StageConfig* stage = nullptr;
  int start = 0;  // first batch (> 0 when resuming mid-stage)
  StageSummary summary;
  Timer timer;
  double callback_start = 0.0;
  long rays_done = 0;
  double first_total_loss = -1.0;  // the divergence guard's reference
  bool warned_loss_rise = false;
  // Stage wall time without on_batch's own time.
  double Seconds(const RunContext& c) const {
    return timer.Seconds() - (c.callback_seconds - callback_start);
  }
};

SolveResult Solver::RunStages(const SolveOptions& options, SolverState* state) {
  SolveResult result;
  RunContext c(dataset_, options, state);
  NameBlocks(&c);
  c.resolved_config = SolverConfigToYaml(config_);
  for (ParameterGroup g : options.extra_constant) c.extra_constant.Insert(g);
  c.checkpoint_written = options.resume;
  if (!options.out_dir.empty() && !options.resume) {
    model_->ForEachBlock([&](const std::string&, double* data, int size) {
      c.start_parameters.insert(c.start_parameters.end(), data, data + size);
    });
    c.start_state = *state;
    c.start_bounds = bounds_;
  }
  for (int s = state->stage; s < static_cast<int>(config_.stages.size()); ++s) {
    if (!RunStage(s, &c, &result)) break;
  }
  return result;
}

void Solver::StopOnDivergence(int stage, int batch_index, const std::string& what, RunContext* c) {
  std::string note = "Nothing was written (no --out).";
  if (!c->options.out_dir.empty()) {
    const std::string where = c->options.out_dir + "/checkpoint";
    if (c->checkpoint_written) {
      note = where + " holds the last good state (the last checkpoint before the blow-up).";
    } else {
      // No checkpoint yet in this run: the run's start is the last good state.
      std::size_t i = 0;
      model_->ForEachBlock([&](const std::string&, double* data, int size) {
        std::copy(c->start_parameters.begin() + i, c->start_parameters.begin() + i + size, data);
        i += size;
      });
      *c->state = c->start_state;
      bounds_ = c->start_bounds;
      c->sampler.set_error_cache(c->start_state.error_cache);
      Save(c->start_state.stage, c->start_state.batch, c);
      note = where + " holds the state the run started from.";
    }
  }
  throw DivergenceError(internal::DivergenceMessage(config_.stages[stage], stage,
                                                    static_cast<int>(config_.stages.size()),
                                                    batch_index, what, note));
}

void Solver::NameBlocks(RunContext* c) {
  c->block_names.clear();
  model_->ForEachBlock(
      [&](const std::string& name, double* data, int) { c->block_names[data] = name; });
}

void Solver::Save(int stage, int batch_index, RunContext* c) {
  if (c->options.out_dir.empty()) return;
  SolverState* state = c->state;
  state->stage = stage;
  state->batch = batch_index;
  state->error_cache = c->sampler.error_cache();
  state->bounds = bounds_;
  model_->set_canonical_bounds(bounds_);
  CheckpointInfo info{stage, batch_index, c->resolved_config};
  SaveCheckpoint(c->options.out_dir + "/checkpoint", *model_, info, state->Serialize());
  c->checkpoint_written = true;
}

bool Solver::RunStage(int s, RunContext* c, SolveResult* result) {
  const SolveOptions& options = c->options;
  SolverState* state = c->state;
  StageRun run;
  run.index = s;
  run.stage = &config_.stages[s];
  const StageConfig& stage = *run.stage;
  const bool resuming_stage = s == state->stage && state->batch > 0;
  run.start = resuming_stage ? state->batch : 0;
  if (!resuming_stage) state->lm_radius = -1.0;
  if (!resuming_stage && s > 0 &&
      config_.stages[s - 1].bone_steps_articulated != stage.bone_steps_articulated) {
    // The bone transforms' tangent space changes (3 B + 3 against 6 B):
    // their Adam moments, temporal bases' included, start again.
    state->DropAdamMoments({ParameterGroup::kBonesT});
  }
  run.summary.name = stage.name;
  StageProblem problem(model_.get(), stage, c->extra_constant);
  run.timer.Reset();
  run.callback_start = c->callback_seconds;
  c->Say(SolveMessageKind::kStage, stage, run.start,
         StrPrintf("stage %d/%zu: %d batches x %d rays, %d samples, step rule %s", s + 1,
                   config_.stages.size(), stage.batches, stage.batch_rays, stage.samples_per_ray,
                   EnumName(stage.step_rule)));
  for (int batch_index = run.start; batch_index < stage.batches; ++batch_index) {
    if (g_interrupted ||
        (options.stop_after_batches >= 0 && state->total_batches >= options.stop_after_batches)) {
      Save(s, batch_index, c);
      result->interrupted = true;
      result->stopped = !g_interrupted;
      c->Say(SolveMessageKind::kStage, stage, batch_index,
             StrPrintf("stopped at batch %d; checkpoint written%s", batch_index,
                       options.out_dir.empty() ? " (none: no --out)" : ""));
      run.summary.batches = batch_index - run.start;
      result->stages.push_back(run.summary);
      return false;
    }
    try {
      RunBatch(batch_index, &run, &problem, c, result);
    } catch (const DivergenceError& e) {
      StopOnDivergence(s, batch_index, e.what(), c);
    }
  }
  problem.ClearMinibatch();
  // Registrations at the stage's end (`at` 1.0): after its last step, before
  // the checkpoint of the next stage.
  RegisterBones(stage.batches, stage, &problem, c);
  StageSummary& summary = run.summary;
  summary.batches = stage.batches - run.start;
  summary.seconds = run.Seconds(*c);
  summary.rays_per_second = run.rays_done / std::max(summary.seconds, 1e-9);
  model_->ForEachBlock([&](const std::string&, double* data, int size) {
    for (int k = 0; k < size; ++k) summary.finite = summary.finite && std::isfinite(data[k]);
  });
  result->stages.push_back(summary);
  state->batch = 0;
  Save(s + 1, 0, c);
  c->Say(SolveMessageKind::kStage, stage, stage.batches,
         StrPrintf("done: %d batches in %.1f s (%.0f rays/s), beta %.4g%s", summary.batches,
                   summary.seconds, summary.rays_per_second, std::exp(*model_->log_beta()),
                   summary.finite ? "" : " -- NON-FINITE PARAMETERS"));
  return true;
}

void Solver::RunBatch(int batch_index, StageRun* run, StageProblem* problem, RunContext* c,
                      SolveResult* result) {
  const StageConfig& stage = *run->stage;
  SolverState* state = c->state;
  const double fraction = static_cast<double>(batch_index) / std::max(1, stage.batches);
  RunSchedules(batch_index, fraction, *run, problem, c, result);

  // ---- The minibatch. ----
  problem->ClearMinibatch();
  problem->ScheduleGroups(batch_index);
  std::vector<Ray> rays = SampleRays(stage, fraction, problem->batch(), &c->sampler, &state->rng);
  const Eigen::Matrix3Xd grid =
      UniformPoints(bounds_, stage.sampling.match_grid_points, &state->rng);
  problem->SetMinibatch(std::move(rays), grid, bounds_, &state->rng);

  // ---- The step. ----
  // Losses at the batch's starting point, for progress and active sampling,
  // from the batch's value cache (Adam: filled by its gradient evaluation,
  // so no extra forward pass).
  const RayBatch& batch = problem->batch();
  TermLosses losses;
  auto record_losses = [&] {
    std::vector<double> errors(batch.num_rays(), 0.0);
    for (int r = 0; r < batch.num_rays(); ++r) {
      const RayEvaluation& ev = batch.evaluation(r);
      const int n = batch.rays()[r].NumSamples();
      for (LossTerm term : RayTerms()) {
        const int row = ev.term_row[static_cast<int>(term)];
        if (row < 0) continue;
        double sq = 0.0;
        for (int k = 0; k < LossTermResiduals(term, n); ++k) {
          sq += ev.residuals[row + k] * ev.residuals[row + k];
        }
        losses[LossTermName(term)] += 0.5 * sq / batch.num_rays();
        if (term == LossTerm::kRgb || term == LossTerm::kSilhouette) errors[r] += sq;
      }
    }
    c->sampler.RecordErrors(batch.rays(), errors);
  };
  StepContext step;
  step.problem = problem;
  step.stage = &stage;
  step.state = state;
  step.batch = batch_index;
  step.adam_gradient_from_ceres = c->options.adam_gradient_from_ceres;
  step.block_names = &c->block_names;
  TakeStep(step, record_losses);
  problem->Restore();
  internal::CheckFiniteAfterBatch(losses, *model_, bounds_, stage,
                                  LearningRate(stage.adam, batch_index, stage.batches));
  if (internal::LossRoseSharply(losses, &run->first_total_loss) && !run->warned_loss_rise) {
    run->warned_loss_rise = true;
    std::ostringstream text;
    text << "batch " << batch_index + 1 << ": the total loss rose above "
         << internal::kLossRiseFactor << " x its value at the stage's first batch ("
         << run->first_total_loss << "): the solve may be diverging; lower adam.lr or the "
         << "largest loss weight if it does not recover";
    c->Say(SolveMessageKind::kWarning, stage, batch_index + 1, text.str());
  }

  run->rays_done += batch.num_rays();
  ++state->total_batches;
  if (batch_index == run->start) run->summary.first_losses = losses;
  run->summary.last_losses = losses;
  ReportBatch(batch_index, *run, losses, c);
  const bool last = batch_index + 1 == stage.batches;
  if (stage.checkpoint_every > 0 && (batch_index + 1) % stage.checkpoint_every == 0 && !last) {
    Save(run->index, batch_index + 1, c);
  }
  if (c->options.on_batch) {
    Timer callback_timer;
    BatchProgress progress;
    progress.stage = run->index;
    progress.stage_name = stage.name;
    progress.batch = batch_index + 1;
    progress.stage_batches = stage.batches;
    progress.total_batches = state->total_batches;
    progress.solve_seconds = c->run_timer.Seconds() - c->callback_seconds;
    progress.losses = losses;
    c->options.on_batch(progress, *model_);
    c->callback_seconds += callback_timer.Seconds();
  }
}

void Solver::ReportBatch(int batch_index, const StageRun& run, const TermLosses& losses,
                         RunContext* c) const {
  const StageConfig& stage = *run.stage;
  const bool last = batch_index + 1 == stage.batches;
  if (!c->Says(SolveMessageKind::kBatch) ||
      !(batch_index % std::max(1, stage.log_every) == 0 || last)) {
    return;
  }
  const double secs = run.Seconds(*c);
  const double rate = run.rays_done / std::max(secs, 1e-9);
  const double eta = (stage.batches - batch_index - 1) * stage.batch_rays / std::max(rate, 1e-9);
  std::string text = StrPrintf("%5d/%d", batch_index + 1, stage.batches);
  double total = 0.0;
  for (const auto& [name, value] : losses) {
    text += StrPrintf(" %s=%.4g", name.c_str(), value);
    total += value;
  }
  text += StrPrintf(" | total=%.4g", total);
  if (const std::optional<RootPoseErrors> e = ComputeRootPoseErrors(*model_, dataset_)) {
    text += StrPrintf(" | root rot err %.1f/%.1f deg", e->mean_deg, e->p90_deg);
    if (model_->num_bones() > 0) {
      const std::optional<RootPoseErrors> body = ComputeBodyPoseErrors(*model_, dataset_);
      text += StrPrintf(", body %.1f/%.1f", body->mean_deg, body->p90_deg);
    }
  }
  text += StrPrintf(" | %.0f rays/s | ETA %.0fs", rate, eta);
  c->Say(SolveMessageKind::kBatch, stage, batch_index + 1, std::move(text));
}

std::vector<Ray> Solver::SampleRays(const StageConfig& stage, double fraction,
                                    const RayBatch& batch, RaySampler* sampler, std::mt19937* rng) {
  Model& model = *model_;
  std::vector<Ray> rays = sampler->Sample(stage.batch_rays, stage.samples_per_ray,
                                          SamplingAt(stage, fraction), model, bounds_, rng);
  if (stage.sampling.importance_depth) {
    // Half the samples stay stratified, half are drawn from the rendering
    // weights of a first pass (NeRF's hierarchical sampling, one level).
    // Only the rendering weights tau are read, and they do not depend on the
    // loss weights: the silhouette alone keeps the pass cheap.
    RayBatchOptions coarse_options = batch.options();
    coarse_options.weights = RayLossWeights::Only({LossTerm::kSilhouette});
    RayBatch coarse(&model, coarse_options);
    coarse.SetDeltaSkinning(batch.delta_skinning());
    coarse.SetRays(rays);
    coarse.EvaluateAll(false);
    for (int r = 0; r < coarse.num_rays(); ++r) {
      ImportanceResample(coarse.evaluation(r).tau, stage.sampling.importance_samples,
                         &rays[r].samples, rng,
                         stage.sampling.min_sdf_sample ? &coarse.evaluation(r).sdf : nullptr);
    }
  }
  return rays;
}

// Schedules fire at their batch also when a resumed run starts there:
// checkpoints are written before a batch's schedules run.
void Solver::RunSchedules(int batch_index, double fraction, const StageRun& run,
                          StageProblem* problem, RunContext* c, SolveResult* result) {
  const StageConfig& stage = *run.stage;
  Model& model = *model_;
  if (stage.schedule.anneal_end_fraction > 0) {
    const double alpha = model.field().options().position_encoding.num_bands *
                         std::min(1.0, fraction / stage.schedule.anneal_end_fraction);
    model.SetFieldAnnealing(alpha);
  }
  if (stage.schedule.bounds_refresh_every > 0 && batch_index > 0 &&
      batch_index % stage.schedule.bounds_refresh_every == 0) {
    RefreshBounds(batch_index, stage, c, result);
  }
  if (fraction >= stage.schedule.neus_from && model.options().density != DensityModel::kNeus) {
    model.SetDensity(DensityModel::kNeus);
    problem->batch().Invalidate();  // cached values rendered with the old density
    c->Say(SolveMessageKind::kEvent, stage, batch_index,
           StrPrintf("density: NeuS from batch %d on", batch_index));
  }
  for (double at : stage.schedule.bone_reinit_at) {
    if (model.num_bones() > 0 && batch_index == stage.BatchAt(at)) {
      ReinitializeBones(batch_index, stage, c);
      const int freeze = stage.BatchAt(stage.schedule.freeze_after_reinit);
      if (freeze > 0) {
        c->Say(SolveMessageKind::kEvent, stage, batch_index,
               StrPrintf("bones re-initialised; shape, appearance and root held for %d batches",
                         freeze));
      }
    }
  }
  RegisterBones(batch_index, stage, problem, c);
  // Automatic model sizing (optim/auto_size.h), first stage only.
  const AutoSizeOptions& auto_size = config_.model.auto_size;
  for (double at : auto_size.grow_at) {
    if (!auto_size.enabled || run.index != 0 || batch_index != stage.BatchAt(at)) {
      continue;
    }
    Grow(batch_index, run, problem, c, result);
  }
  bool solve_poses =
      stage.pose_solve.every > 0 && batch_index > 0 && batch_index % stage.pose_solve.every == 0;
  for (double at : stage.pose_solve.at)
    solve_poses = solve_poses || batch_index == stage.BatchAt(at);
  if (solve_poses) SolvePoses(batch_index, run, problem, c, result);
}

void Solver::SolvePoses(int batch_index, const StageRun& run, StageProblem* problem, RunContext* c,
                        SolveResult* result) {
  const StageConfig& stage = *run.stage;
  if (stage.pose_solve.featureless_only && dataset_.HasPixelFeatures()) return;
  FramePoseContext context;
  context.batch = problem->batch().options();
  context.batch.weights[LossTerm::kCycle3d] = 0.0;  // no view of the pose
  context.robust = problem->ray_robust();
  context.delta_skinning = problem->batch().delta_skinning();
  context.match_grid = UniformPoints(bounds_, stage.sampling.match_grid_points, &c->state->rng);
  // The root only once the schedule frees it (root_free_from).
  context.solve_root = !problem->ConfiguredConstant(ParameterGroup::kRoot) &&
                       batch_index >= stage.BatchAt(stage.schedule.root_free_from);
  context.solve_bones = stage.pose_solve.bones && model_->num_bones() > 0;
  if (!context.solve_root && !context.solve_bones) return;
  context.bone_steps_about_centres = stage.bone_steps_about_centres;
  PoseSolveReport report =
      SolveAllFramePoses(model_.get(), c->sampler, stage, bounds_, context, &c->state->rng);
  report.stage = run.index;
  report.batch = batch_index;
  // The solved blocks jumped: their Adam moments are stale.
  if (context.solve_root) c->state->DropAdamMoments({ParameterGroup::kRoot});
  if (context.solve_bones) c->state->DropAdamMoments({ParameterGroup::kBonesT});
  problem->batch().Invalidate();
  if (c->Says(SolveMessageKind::kEvent)) {
    std::string text = report.Describe();
    if (const std::optional<RootPoseErrors> e = ComputeRootPoseErrors(*model_, dataset_)) {
      text += StrPrintf("; root rotation error now %.1f deg mean, %.1f deg p90", e->mean_deg,
                        e->p90_deg);
    }
    c->Say(SolveMessageKind::kEvent, stage, batch_index, std::move(text));
  }
  result->pose_solves.push_back(std::move(report));
}

void Solver::RegisterBones(int batch_index, const StageConfig& stage, StageProblem* problem,
                           RunContext* c) {
  for (double at : stage.bone_registration.at) {
    if (model_->num_bones() == 0 || batch_index != stage.BatchAt(at)) continue;
    // After the stage's last batch (`at` 1.0): its own weights, if set.
    const BoneRegistrationConfig config = batch_index == stage.batches
                                              ? stage.bone_registration.AfterLastBatch()
                                              : stage.bone_registration;
    const BoneRegistrationReport report = RegisterBoneMotion(
        model_.get(), dataset_, bounds_, config, static_cast<uint32_t>(c->state->rng()));
    if (report.registered) {
      c->state->DropAdamMoments({ParameterGroup::kBonesT});  // the bone transforms jumped
      problem->batch().Invalidate();
    }
    c->Say(SolveMessageKind::kEvent, stage, batch_index, report.Describe());
  }
}

// A grow step of automatic sizing: the problem drops every block, the model
// grows, the blocks come back (new sizes and addresses) and the Adam moments
// follow their entries.
void Solver::Grow(int batch_index, const StageRun& run, StageProblem* problem, RunContext* c,
                  SolveResult* result) {
  const StageConfig& stage = *run.stage;
  Timer grow_timer;
  problem->RemoveAllBlocks();
  AutoSizeRemaps remaps;
  AutoSizeEvent event =
      AutoSizeGrow(config_.model.auto_size, c->sampler, stage.sampling, stage.samples_per_ray,
                   bounds_, &c->state->rng, model_.get(), &remaps);
  event.stage = run.index;
  event.batch = batch_index;
  // A temporal basis's coefficients span every bone of a video: their
  // moments start again when the bones change (AdamConfig::bone_basis).
  c->state->DropAdamBasisMoments();
  for (auto& [name, moments] : c->state->adam) {
    if (const TangentRemap* remap = remaps.For(name)) remap->Apply(&moments.m, &moments.v);
  }
  NameBlocks(c);
  problem->AddModelBlocks();
  problem->batch().Invalidate();
  event.seconds = grow_timer.Seconds();
  c->Say(SolveMessageKind::kEvent, stage, batch_index, event.Describe());
  result->auto_size.push_back(std::move(event));
}

}  // namespace banmo

namespace banmo {

void Solver::RefreshBounds(int batch_index, const StageConfig& stage, RunContext* c,
                           SolveResult* result) {
  const BoundsRefreshResult r = RefreshCanonicalBounds(*model_, dataset_, bounds_,
                                                       stage.schedule.bounds_refresh_max_mask_loss);
  if (r.kept > 0.0) {
    ++result->bounds_refreshes_held;
    const Eigen::Vector3d from = bounds_.sizes(), surface = r.surface.sizes(), to = r.box.sizes();
    c->Say(SolveMessageKind::kEvent, stage, batch_index,
           StrPrintf("bounds refresh at batch %d held: the surface's box (%.2f x %.2f x %.2f) "
                     "meets %.1f %% of the masks' object pixels against %.1f %% of the box "
                     "before (%.2f x %.2f x %.2f); new box %.0f %% of the way back (%.2f x %.2f "
                     "x %.2f, %.1f %%)",
                     batch_index, surface[0], surface[1], surface[2], 100.0 * r.coverage_surface,
                     100.0 * r.coverage_current, from[0], from[1], from[2], 100.0 * r.kept, to[0],
                     to[1], to[2], 100.0 * r.coverage));
  }
  bounds_ = r.box;
}

void Solver::ReinitializeBones(int batch_index, const StageConfig& stage, RunContext* c) {
  const bool keep_motion = stage.schedule.bone_reinit_keep_motion;
  const BoneSites sites = stage.schedule.bone_sites;
  SolverState* state = c->state;
  Model& model = *model_;
  const int B = model.num_bones();
  ExtractOptions options;
  options.grid.resolution = 48;
  options.min_component_fraction = 1.0;  // bone sites on the largest component
  options.grid.bounds_min = bounds_.min();
  options.grid.bounds_max = bounds_.max();
  TriangleMesh mesh;
  try {
    mesh = ExtractCanonicalMesh(model, options);
  } catch (const InputError&) {
    return;  // no surface yet: keep the bones
  }
  if (mesh.NumVertices() < B) return;
  const uint32_t seed = static_cast<uint32_t>(state->rng());
  std::vector<Eigen::Vector3d> centres;
  if (sites == BoneSites::kSkeleton) {
    try {
      centres = BoneCentresFromSkeleton(mesh, B, seed);
    } catch (const InputError& e) {
      // A coarse surface can be too rough for a skeleton: the surface's
      // k-means still places the bones.
      c->Say(
          SolveMessageKind::kWarning, stage, batch_index,
          StrPrintf("bone re-initialisation: %s; bone centres from the surface instead", e.what()));
    }
  }
  if (centres.empty()) centres = BoneCentresFromSurface(mesh, B, seed);
  const std::vector<double> old_bones(model.bones(), model.bones() + kBoneSize * B);
  InitializeBones(centres, model.options().init_bone_scale, model.bones());
  for (int v = 0; v < model.num_videos(); ++v) {
    for (size_t t = 0; t < model.video(v).frames.size(); ++t) {
      double* bones_t = model.frame(v, t).bones_t.data();
      if (keep_motion) {
        const std::vector<double> old_t(bones_t, bones_t + kPoseSize * B);
        TransferBoneMotion(B, old_bones.data(), old_t.data(), B, model.bones(), bones_t);
      } else {
        for (int b = 0; b < B; ++b) PoseSetIdentity(bones_t + kPoseSize * b);
      }
    }
  }
  // Delta logits were learnt for the old bones: back to zero (the output
  // layer), so the new bones start from the Gaussian weights alone.
  if (model.has_delta_skinning()) {
    const Mlp& mlp = model.delta_skinning()->mlp();
    const int last = mlp.NumLinearLayers() - 1;
    std::fill(model.delta_skinning_params() + mlp.WeightOffset(last),
              model.delta_skinning_params() + mlp.NumParameters(), 0.0);
  }
  // The Adam moments of the bones, their transforms (and bases) and
  // MLP_Delta's weights (not the rest pose code's, which keeps its value).
  state->DropAdamMoments({ParameterGroup::kBones, ParameterGroup::kBonesT});
  state->adam.erase("delta_skinning");
}

}  // namespace banmo
