// The stage-by-stage solver (docs/solver.md, docs/design.md): for each stage of the
// config, minibatches of rays become residual blocks of one persistent
// ceres::Problem (parameter blocks, manifolds and constant groups are set up
// once per stage; the batch's residual blocks are replaced every iteration),
// and a step rule moves the parameters:
//   lm        Ceres TRUST_REGION / LEVENBERG_MARQUARDT, CGNR (or
//             ITERATIVE_SCHUR), one LM iteration per minibatch, the radius
//             carried from batch to batch with a cap;
//   adam      AdamW with a one-cycle schedule on the gradient of the
//             problem's cost (RayBatch::EvaluateGradient for the ray terms,
//             the regularisers' cost functions, each block's PlusJacobian:
//             what ceres::Problem::Evaluate gives, without forming the rays'
//             Jacobians; manifolds and constant blocks respected: steps are
//             taken in the tangent space);
//   alternate Adam on every block but the per-frame root corrections (and
//             with pose_solve.bones the bone transforms), which move only
//             in the stage's frame-major LM pose solves (pose_solve.every /
//             at; optim/pose_solve.h).
// With model.auto_size the model grows at fractions of the first stage
// (optim/auto_size.h): the stage's problem drops its blocks, the model
// grows, the blocks are added again and the Adam moments follow their
// entries. Checkpoints are atomic, on a schedule and on SIGINT; a resumed
// run gives the same result as an uninterrupted one with the same seed.
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "banmo/io/dataset.h"
#include "banmo/losses/ray.h"
#include "banmo/model/make_model.h"
#include "banmo/model/model.h"
#include "banmo/optim/auto_size.h"
#include "banmo/optim/config.h"
#include "banmo/optim/pose_solve_report.h"
#include "banmo/optim/solve_reporter.h"

namespace banmo {

// phi_k(t) of the temporal step bases (AdamConfig::bone_basis / root_basis):
// the cosines of a DCT-II over `frames` frames, scaled so that
// sum_k phi_k(t)^2 is about 1 for num_coefficients of them (exactly 1 when
// num_coefficients == frames): a frame's step is about lr, as without a basis.
double TemporalBasisValue(int k, int t, int frames, int num_coefficients);

class RayBatch;
class RaySampler;
class StageProblem;
struct SolverState;

// Per-term mean losses (1/2 |r|^2 per ray, after weights) of the last batch.
using TermLosses = std::map<std::string, double>;

// What SolveOptions::on_batch sees after each batch.
struct BatchProgress {
  int stage = 0;               // index into config.stages
  std::string stage_name;      //
  int batch = 0;               // batches done in this stage (1-based)
  int stage_batches = 0;       // batches of this stage
  int total_batches = 0;       // batches done in all stages
  double solve_seconds = 0.0;  // wall time of this Run so far, without on_batch's own time
  TermLosses losses;           // the batch's per-term losses
};

struct SolveOptions {
  std::string out_dir;  // checkpoints go to out_dir/checkpoint (empty: no checkpoints)
  bool resume = false;  // continue from out_dir/checkpoint
  bool quiet = false;   // no progress lines or events (warnings are still reported)
  // Where progress lines, events and warnings go (optim/solve_reporter.h);
  // null: a PrintingReporter (stdout, warnings through glog). Not owned.
  SolveReporter* reporter = nullptr;
  // Parameter groups held constant in every stage on top of the stage's own
  // (retargeting freezes the shared ones).
  std::vector<ParameterGroup> extra_constant;
  // Stop after this many batches in total (for tests of resume; <0 = no limit).
  int stop_after_batches = -1;
  // Adam's gradient from ceres::Problem::Evaluate (full per-row Jacobians of
  // every ray term) instead of RayBatch::EvaluateGradient (one cotangent row
  // per ray). Same gradient to rounding, several times slower; kept as the
  // reference for tests and timings.
  bool adam_gradient_from_ceres = false;
  // Called after every batch when set (benchmark traces: evaluate the model
  // at chosen points). Its own run time is excluded from the stage timers,
  // rays/s and BatchProgress::solve_seconds. It must not change the model.
  std::function<void(const BatchProgress&, const Model&)> on_batch;
};

struct StageSummary {
  std::string name;
  int batches = 0;  // batches run in this call (fewer after a resume or a stop)
  double seconds = 0.0;
  double rays_per_second = 0.0;
  TermLosses first_losses;  // first batch of the stage
  TermLosses last_losses;   // last batch of the stage
  bool finite = true;       // every parameter finite at the end
};

struct SolveResult {
  std::vector<StageSummary> stages;
  // Grow steps of automatic sizing (model.auto_size), in order.
  std::vector<AutoSizeEvent> auto_size;
  // Per-frame pose solves (stage pose_solve.at), in order.
  std::vector<PoseSolveReport> pose_solves;
  // Bounds refreshes whose surface box lost too much of the masks
  // (optim/bounds_refresh.h): the box was kept nearer the old one.
  int bounds_refreshes_held = 0;
  bool interrupted = false;  // stopped by SIGINT or stop_after_batches (checkpoint written)
  bool stopped = false;      // ... by stop_after_batches (as asked, not SIGINT)
};

class Solver {
 public:
  // The solver keeps references to dataset and config.
  Solver(const Dataset& dataset, const SolverConfig& config, std::unique_ptr<Model> model);
  ~Solver();

  Model& model() { return *model_; }
  const Model& model() const { return *model_; }
  // Canonical bounds used for near/far planes, eikonal points and the
  // soft-argmax grid.
  const Eigen::AlignedBox3d& canonical_bounds() const { return bounds_; }

  SolveResult Run(const SolveOptions& options);

 private:
  struct RunContext;
  struct StageRun;
  SolveResult RunStages(const SolveOptions& options, SolverState* state);
  // One stage; false when the run was interrupted (checkpoint written).
  bool RunStage(int stage, RunContext* c, SolveResult* result);
  // One batch: schedules, minibatch, step, progress, checkpoint.
  void RunBatch(int batch_index, StageRun* run, StageProblem* problem, RunContext* c,
                SolveResult* result);
  // Annealing, bounds refresh, bone re-initialisation, automatic sizing,
  // pose solves.
  void RunSchedules(int batch_index, double fraction, const StageRun& run, StageProblem* problem,
                    RunContext* c, SolveResult* result);
  // The bone registrations of the stage's bone_registration.at that fire at
  // batch_index (the stage's batch count: after its last batch, with
  // bone_registration.after_last_batch's weights).
  void RegisterBones(int batch_index, const StageConfig& stage, StageProblem* problem,
                     RunContext* c);
  void Grow(int batch_index, const StageRun& run, StageProblem* problem, RunContext* c,
            SolveResult* result);
  // Every frame's root pose by LM on its own rays (optim/pose_solve.h).
  void SolvePoses(int batch_index, const StageRun& run, StageProblem* problem, RunContext* c,
                  SolveResult* result);
  // The minibatch's rays at `fraction` of the stage (SamplingAt), with
  // importance-resampled depths when the stage asks for them.
  std::vector<Ray> SampleRays(const StageConfig& stage, double fraction, const RayBatch& batch,
                              RaySampler* sampler, std::mt19937* rng);
  // The progress line of a batch (every stage.log_every batches and the
  // stage's last) to the reporter.
  void ReportBatch(int batch_index, const StageRun& run, const TermLosses& losses,
                   RunContext* c) const;
  void NameBlocks(RunContext* c);
  // Writes out_dir/checkpoint (nothing without out_dir).
  void Save(int stage, int batch_index, RunContext* c);
  // The divergence guard's stop (optim/divergence_guard.h): leaves the last
  // good state as the checkpoint and throws DivergenceError naming the
  // stage, the batch and `what` blew up.
  [[noreturn]] void StopOnDivergence(int stage, int batch_index, const std::string& what,
                                     RunContext* c);
  // Canonical bounds from a coarse extraction of the current surface (10 %
  // margin, within [-2, 2]^3), checked against the masks
  // (optim/bounds_refresh.h, schedule.bounds_refresh_max_mask_loss);
  // unchanged if the level set is empty.
  void RefreshBounds(int batch_index, const StageConfig& stage, RunContext* c, SolveResult* result);
  // Rest bones re-initialised on the current surface (k-means of a coarse
  // extraction), bone transforms reset to the identity (keep_motion: set to
  // carry each frame's old motion, TransferBoneMotion), MLP_Delta's output
  // layer reset to zero (its logits belonged to the old bones), their Adam
  // moments cleared (the stage's schedule.bone_reinit_keep_motion and
  // bone_sites).
  void ReinitializeBones(int batch_index, const StageConfig& stage, RunContext* c);

  const Dataset& dataset_;
  const SolverConfig& config_;
  std::unique_ptr<Model> model_;
  Eigen::AlignedBox3d bounds_;
};

}  // namespace banmo
