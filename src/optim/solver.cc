#include "banmo/optim/solver.h"

#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>
#include <sstream>

#include "banmo/deform/bone_centres.h"
#include "banmo/extract/extract.h"
#include "banmo/geometry/pose_manifold.h"
#include "banmo/losses/ray_batch.h"
#include "banmo/losses/regularizers.h"
#include "banmo/optim/auto_size.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/ray_sampler.h"
#include "banmo/render/ray_samples.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace {

std::atomic<bool> g_interrupted{false};
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

std::unique_ptr<ceres::LossFunction> MakeRobustLoss(const RobustLossConfig& c) {
  if (c.type == "none") return nullptr;
  if (c.type == "huber") return std::make_unique<ceres::HuberLoss>(c.scale);
  if (c.type == "cauchy") return std::make_unique<ceres::CauchyLoss>(c.scale);
  if (c.type == "soft_l1") return std::make_unique<ceres::SoftLOneLoss>(c.scale);
  if (c.type == "arctan") return std::make_unique<ceres::ArctanLoss>(c.scale);
  if (c.type == "tolerant") return std::make_unique<ceres::TolerantLoss>(c.scale, c.scale);
  ThrowInputError("robust.type: unknown robust loss '", c.type, "'");
}

RayLossWeights WeightsOf(const LossesConfig& l) {
  RayLossWeights w;
  w.rgb = l.rgb.weight;
  w.silhouette = l.silhouette.weight;
  w.flow = l.flow.weight;
  w.feature_match = l.feature_match.weight;
  w.cycle_2d = l.cycle_2d.weight;
  w.cycle_3d = l.cycle_3d.weight;
  return w;
}

const LossConfig& TermConfig(const LossesConfig& l, LossTerm term) {
  switch (term) {
    case LossTerm::kRgb:
      return l.rgb;
    case LossTerm::kSilhouette:
      return l.silhouette;
    case LossTerm::kFlow:
      return l.flow;
    case LossTerm::kFeatureMatch:
      return l.feature_match;
    case LossTerm::kCycle2d:
      return l.cycle_2d;
    case LossTerm::kCycle3d:
      return l.cycle_3d;
  }
  return l.rgb;
}

// One-cycle learning rate (Smith 2018, as in BANMo's training): linear warm-up
// from lr/25 to lr over warmup_fraction, then cosine decay to
// lr * final_lr_fraction.
double LearningRate(const AdamConfig& a, int iteration, int iterations) {
  if (a.schedule == "constant") return a.lr;
  const double x = iterations > 1 ? static_cast<double>(iteration) / (iterations - 1) : 1.0;
  if (x < a.warmup_fraction) {
    const double s = a.warmup_fraction > 0 ? x / a.warmup_fraction : 1.0;
    return a.lr * (0.04 + 0.96 * s);
  }
  const double s =
      a.warmup_fraction < 1 ? (x - a.warmup_fraction) / (1.0 - a.warmup_fraction) : 1.0;
  const double lo = a.lr * a.final_lr_fraction;
  return lo + 0.5 * (a.lr - lo) * (1.0 + std::cos(M_PI * s));
}

void AppendPod(std::string* out, const void* data, size_t bytes) {
  out->append(static_cast<const char*>(data), bytes);
}
template <typename T>
void Append(std::string* out, const T& v) {
  AppendPod(out, &v, sizeof(T));
}
template <typename T>
T Read(const std::string& in, size_t* pos) {
  if (*pos + sizeof(T) > in.size()) ThrowInputError("checkpoint state.bin: truncated");
  T v;
  std::memcpy(&v, in.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return v;
}

// Adds the gradient of residual block `id`'s cost, 1/2 rho(|r|^2), wrt its
// non-constant parameter blocks to (*gradient)[block] (ambient, rho' J^T r as
// ceres::Problem::Evaluate computes it). Calls the cost function directly, so
// the problem's evaluation callback (the RayBatch) is not triggered.
double AddResidualBlockGradient(const ceres::Problem& problem, ceres::ResidualBlockId id,
                                std::map<const double*, Eigen::VectorXd>* gradient) {
  const ceres::CostFunction* f = problem.GetCostFunctionForResidualBlock(id);
  const ceres::LossFunction* loss = problem.GetLossFunctionForResidualBlock(id);
  std::vector<double*> blocks;
  problem.GetParameterBlocksForResidualBlock(id, &blocks);
  const int rows = f->num_residuals();
  Eigen::VectorXd residuals(rows);
  std::vector<RowMajorMatrix> jac(blocks.size());
  std::vector<double*> jac_ptrs(blocks.size(), nullptr);
  for (size_t i = 0; i < blocks.size(); ++i) {
    if (problem.IsParameterBlockConstant(blocks[i])) continue;
    jac[i].resize(rows, f->parameter_block_sizes()[i]);
    jac_ptrs[i] = jac[i].data();
  }
  CHECK(f->Evaluate(blocks.data(), residuals.data(), jac_ptrs.data()));
  const double sq = residuals.squaredNorm();
  double rho[3] = {sq, 1.0, 0.0};
  if (loss != nullptr) loss->Evaluate(sq, rho);
  for (size_t i = 0; i < blocks.size(); ++i) {
    if (jac_ptrs[i] == nullptr) continue;
    Eigen::VectorXd& sum = (*gradient)[blocks[i]];
    if (sum.size() == 0) sum = Eigen::VectorXd::Zero(jac[i].cols());
    sum.noalias() += rho[1] * (jac[i].transpose() * residuals);
  }
  return 0.5 * rho[0];
}

}  // namespace

// Everything a resumed run needs beyond the model's parameters.
struct Solver::State {
  int stage = 0;
  int iteration = 0;
  int total_batches = 0;
  std::mt19937 rng;
  double lm_radius = -1.0;  // < 0: the stage's initial radius
  struct Moments {
    std::vector<double> m, v;
    int64_t steps = 0;
  };
  std::map<std::string, Moments> adam;  // by block name (Model::ForEachBlock)
  std::vector<RaySampler::CachedPixel> error_cache;
  Eigen::AlignedBox3d bounds;

  std::string Serialize() const {
    std::string out = "BANMOST1";
    Append(&out, stage);
    Append(&out, iteration);
    Append(&out, total_batches);
    Append(&out, lm_radius);
    std::ostringstream rs;
    rs << rng;
    const std::string r = rs.str();
    Append(&out, static_cast<uint64_t>(r.size()));
    out += r;
    Append(&out, static_cast<uint64_t>(adam.size()));
    for (const auto& [name, mo] : adam) {
      Append(&out, static_cast<uint64_t>(name.size()));
      out += name;
      Append(&out, static_cast<uint64_t>(mo.m.size()));
      AppendPod(&out, mo.m.data(), sizeof(double) * mo.m.size());
      AppendPod(&out, mo.v.data(), sizeof(double) * mo.v.size());
      Append(&out, mo.steps);
    }
    Append(&out, static_cast<uint64_t>(error_cache.size()));
    AppendPod(&out, error_cache.data(), sizeof(RaySampler::CachedPixel) * error_cache.size());
    for (int k = 0; k < 3; ++k) Append(&out, bounds.min()[k]);
    for (int k = 0; k < 3; ++k) Append(&out, bounds.max()[k]);
    return out;
  }

  void Deserialize(const std::string& in) {
    if (in.compare(0, 8, "BANMOST1") != 0) ThrowInputError("checkpoint state.bin: bad header");
    size_t pos = 8;
    stage = Read<int>(in, &pos);
    iteration = Read<int>(in, &pos);
    total_batches = Read<int>(in, &pos);
    lm_radius = Read<double>(in, &pos);
    const uint64_t rn = Read<uint64_t>(in, &pos);
    std::istringstream rs(in.substr(pos, rn));
    rs >> rng;
    pos += rn;
    const uint64_t na = Read<uint64_t>(in, &pos);
    adam.clear();
    for (uint64_t i = 0; i < na; ++i) {
      const uint64_t ln = Read<uint64_t>(in, &pos);
      const std::string name = in.substr(pos, ln);
      pos += ln;
      const uint64_t n = Read<uint64_t>(in, &pos);
      Moments mo;
      mo.m.resize(n);
      mo.v.resize(n);
      for (auto& x : mo.m) x = Read<double>(in, &pos);
      for (auto& x : mo.v) x = Read<double>(in, &pos);
      mo.steps = Read<int64_t>(in, &pos);
      adam[name] = std::move(mo);
    }
    const uint64_t nc = Read<uint64_t>(in, &pos);
    error_cache.resize(nc);
    for (auto& c : error_cache) c = Read<RaySampler::CachedPixel>(in, &pos);
    Eigen::Vector3d lo, hi;
    for (int k = 0; k < 3; ++k) lo[k] = Read<double>(in, &pos);
    for (int k = 0; k < 3; ++k) hi[k] = Read<double>(in, &pos);
    bounds = Eigen::AlignedBox3d(lo, hi);
  }
};

Solver::Solver(const Dataset& dataset, const SolverConfig& config, std::unique_ptr<Model> model)
    : dataset_(dataset), config_(config), model_(std::move(model)) {
  CHECK(model_ != nullptr);
  // GT is normalised to a largest half-extent of 1 (docs/dataset.md); the
  // bounds start a little larger and are refreshed from the surface.
  bounds_ = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1.2), Eigen::Vector3d::Constant(1.2));
}

Solver::~Solver() = default;

SolveResult Solver::Run(const SolveOptions& options) {
  State state;
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
  }
  // The model records how it is trained (saved with it, model/model_file.h).
  if (!config_.stages.empty()) {
    const StageConfig& last = config_.stages.back();
    model_->set_training_sampling(TrainingSampling{
        last.samples_per_ray, last.sampling.near_far_margin, last.sampling.importance_depth});
  }
  SigintGuard guard;
  if (config_.threads > 0) SetNumThreads(config_.threads);
  SolveResult result = RunStages(options, &state);
  model_->set_canonical_bounds(bounds_);
  return result;
}

SolveResult Solver::RunStages(const SolveOptions& options, State* state) {
  SolveResult result;
  Timer run_timer;
  double callback_seconds = 0.0;  // time inside options.on_batch (excluded from timings)
  Model& model = *model_;
  int B = model.num_bones();  // grows with automatic sizing
  RaySampler sampler(dataset_);
  sampler.set_error_cache(state->error_cache);
  std::map<const double*, std::string> block_names;
  auto name_blocks = [&] {
    block_names.clear();
    model.ForEachBlock(
        [&](const std::string& name, double* data, int) { block_names[data] = name; });
  };
  name_blocks();
  const std::string resolved_config = SolverConfigToYaml(config_);

  auto save = [&](int stage, int iteration) {
    if (options.out_dir.empty()) return;
    state->stage = stage;
    state->iteration = iteration;
    state->error_cache = sampler.error_cache();
    state->bounds = bounds_;
    model.set_canonical_bounds(bounds_);
    CheckpointInfo info{stage, iteration, resolved_config};
    SaveCheckpoint(options.out_dir + "/checkpoint", model, info, state->Serialize());
  };

  for (int s = state->stage; s < static_cast<int>(config_.stages.size()); ++s) {
    const StageConfig& stage = config_.stages[s];
    const bool resuming_stage = s == state->stage && state->iteration > 0;
    const int start = resuming_stage ? state->iteration : 0;
    if (!resuming_stage) state->lm_radius = -1.0;
    StageSummary summary;
    summary.name = stage.name;

    // ---- Problem set-up for this stage. ----
    RayBatchOptions batch_options;
    batch_options.weights = WeightsOf(stage.losses);
    batch_options.match_top_k = stage.sampling.match_top_k;
    batch_options.matcher.exact = true;  // deterministic (FLANN's trees are randomised)
    RayBatch batch(&model, batch_options);
    ceres::Problem::Options problem_options;
    problem_options.evaluation_callback = &batch;
    problem_options.enable_fast_removal = true;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);

    std::set<std::string> constant(stage.constant.begin(), stage.constant.end());
    constant.insert(options.extra_constant.begin(), options.extra_constant.end());
    // Blocks by group, for constancy and for the alternate rule.
    std::map<std::string, std::vector<double*>> groups;
    auto add_block = [&](const std::string& group, double* data, int size,
                         std::unique_ptr<ceres::Manifold> manifold) {
      if (size == 0) return;
      problem.AddParameterBlock(data, size, manifold.release());
      groups[group].push_back(data);
    };
    // Every block with its manifold and constancy (again after a grow step
    // of automatic sizing, which moves blocks).
    auto add_model_blocks = [&] {
      groups.clear();
      add_block("sdf", model.sdf(), model.sdf_size(), nullptr);
      add_block("color", model.color(), model.color_size(), nullptr);
      add_block("embedding", model.embedding(), model.embedding_size(), nullptr);
      add_block("log_beta", model.log_beta(), 1, nullptr);
      if (B > 0) {
        add_block("bones", model.bones(), model.bones_size(),
                  MakeStackedQuaternionBlockManifold(B, kBoneSize, kBoneQw));
      }
      if (model.has_delta_skinning()) {
        add_block("delta_skinning", model.delta_skinning_params(), model.delta_skinning_size(),
                  nullptr);
        add_block("delta_skinning", model.rest_pose_code(), model.pose_code_size(), nullptr);
      }
      for (int v = 0; v < model.num_videos(); ++v) {
        add_block("intrinsics", model.video(v).intrinsics.data(), kIntrinsicsSize, nullptr);
        add_block("appearance", model.video(v).appearance.data(), model.appearance_size(), nullptr);
        for (size_t t = 0; t < model.video(v).frames.size(); ++t) {
          FrameParameters& f = model.frame(v, t);
          add_block("root", f.root_delta.data(), kPoseSize, MakePoseManifold());
          if (B > 0)
            add_block("bones_t", f.bones_t.data(), kPoseSize * B, MakeStackedPoseManifold(B));
          if (model.has_delta_skinning()) {
            add_block("pose_code", f.pose_code.data(), model.pose_code_size(), nullptr);
          }
        }
      }
      for (const std::string& g : constant) {
        for (double* p : groups[g]) problem.SetParameterBlockConstant(p);
      }
    };
    add_model_blocks();
    // Delta skinning (schedule.delta_skinning_from): before the fraction its
    // groups are held constant, and while MLP_Delta's output is still zero
    // the batch leaves it out (same values, no cost).
    const std::set<std::string> configured_constant = constant;
    auto schedule_delta_skinning = [&](double fraction) {
      if (!model.has_delta_skinning()) return;
      const bool free = fraction >= stage.schedule.delta_skinning_from;
      for (const char* g : {"delta_skinning", "pose_code"}) {
        const bool hold = !free || configured_constant.count(g) > 0;
        if (hold) {
          constant.insert(g);
        } else {
          constant.erase(g);
        }
        for (double* p : groups[g]) {
          if (hold) {
            problem.SetParameterBlockConstant(p);
          } else {
            problem.SetParameterBlockVariable(p);
          }
        }
      }
      batch.SetDeltaSkinning((free && !configured_constant.count("delta_skinning")) ||
                             model.DeltaSkinningIsNonZero());
    };
    std::array<std::unique_ptr<ceres::LossFunction>, kNumLossTerms> robust;
    for (int t = 0; t < kNumLossTerms; ++t) {
      robust[t] = MakeRobustLoss(TermConfig(stage.losses, static_cast<LossTerm>(t)).robust);
    }
    auto eikonal_robust = MakeRobustLoss(stage.losses.eikonal.robust);
    auto inside_robust = MakeRobustLoss(stage.losses.bone_inside.robust);
    auto smooth_robust = MakeRobustLoss(stage.losses.pose_smoothness.robust);

    std::vector<ceres::ResidualBlockId> batch_blocks;
    std::vector<ceres::ResidualBlockId> regularizer_blocks;  // of batch_blocks: not ray terms
    RayRobustLosses ray_robust{};
    for (int t = 0; t < kNumLossTerms; ++t) ray_robust[t] = robust[t].get();
    Timer stage_timer;
    const double stage_callback_start = callback_seconds;
    // Stage wall time without on_batch's own time.
    auto stage_seconds = [&] {
      return stage_timer.Seconds() - (callback_seconds - stage_callback_start);
    };
    long rays_done = 0;
    if (!options.quiet) {
      std::printf("[%s] stage %d/%zu: %d batches x %d rays, %d samples, step rule %s\n",
                  stage.name.c_str(), s + 1, config_.stages.size(), stage.iterations,
                  stage.batch_rays, stage.samples_per_ray, stage.step_rule.c_str());
      std::fflush(stdout);
    }

    for (int it = start; it < stage.iterations; ++it) {
      if (g_interrupted ||
          (options.stop_after_batches >= 0 && state->total_batches >= options.stop_after_batches)) {
        save(s, it);
        result.interrupted = true;
        if (!options.quiet) {
          std::printf("[%s] stopped at batch %d; checkpoint written%s\n", stage.name.c_str(), it,
                      options.out_dir.empty() ? " (none: no --out)" : "");
        }
        summary.iterations = it - start;
        result.stages.push_back(summary);
        return result;
      }
      const double fraction = static_cast<double>(it) / std::max(1, stage.iterations);
      if (stage.schedule.anneal_end_fraction > 0) {
        const double alpha = model.field().options().position_encoding.num_bands *
                             std::min(1.0, fraction / stage.schedule.anneal_end_fraction);
        model.SetFieldAnnealing(alpha);
      }

      // ---- Schedules. ----
      if (stage.schedule.bounds_refresh_every > 0 && it > 0 &&
          it % stage.schedule.bounds_refresh_every == 0) {
        RefreshBounds();
      }
      // Schedules fire at their batch also when a resumed run starts there:
      // checkpoints are written before a batch's schedules run.
      for (double at : stage.schedule.bone_reinit_at) {
        if (B > 0 && it == static_cast<int>(std::lround(at * stage.iterations))) {
          ReinitializeBones(state);
        }
      }
      // Automatic model sizing (optim/auto_size.h), first stage only: the
      // problem drops every block, the model grows, the blocks come back
      // (new sizes and addresses) and the Adam moments follow their entries.
      const AutoSizeOptions& auto_size = config_.model.auto_size;
      for (double at : auto_size.grow_at) {
        if (!auto_size.enabled || s != 0 ||
            it != static_cast<int>(std::lround(at * stage.iterations))) {
          continue;
        }
        Timer grow_timer;
        for (ceres::ResidualBlockId id : batch_blocks) problem.RemoveResidualBlock(id);
        batch_blocks.clear();
        regularizer_blocks.clear();
        std::vector<double*> blocks;
        problem.GetParameterBlocks(&blocks);
        for (double* p : blocks) problem.RemoveParameterBlock(p);
        AutoSizeRemaps remaps;
        AutoSizeEvent event =
            AutoSizeGrow(auto_size, sampler, stage.sampling, stage.samples_per_ray, bounds_,
                         &state->rng, &model, &remaps);
        event.stage = s;
        event.iteration = it;
        for (auto& [name, moments] : state->adam) {
          if (const TangentRemap* remap = remaps.For(name)) remap->Apply(&moments.m, &moments.v);
        }
        B = model.num_bones();
        name_blocks();
        add_model_blocks();
        batch.Invalidate();
        event.seconds = grow_timer.Seconds();
        if (!options.quiet) {
          std::printf("[%s] %s\n", stage.name.c_str(), event.Describe().c_str());
          std::fflush(stdout);
        }
        result.auto_size.push_back(std::move(event));
      }

      // ---- The minibatch. ----
      for (ceres::ResidualBlockId id : batch_blocks) problem.RemoveResidualBlock(id);
      schedule_delta_skinning(fraction);
      batch_blocks.clear();
      regularizer_blocks.clear();
      std::vector<Ray> rays = sampler.Sample(stage.batch_rays, stage.samples_per_ray,
                                             stage.sampling, model, bounds_, &state->rng);
      if (stage.sampling.importance_depth) {
        // Half the samples stay stratified, half are drawn from the rendering
        // weights of a first pass (NeRF's hierarchical sampling, one level).
        RayBatchOptions coarse_options = batch_options;
        coarse_options.weights = RayLossWeights();
        coarse_options.weights.feature_match = coarse_options.weights.cycle_2d = 0.0;
        RayBatch coarse(&model, coarse_options);
        coarse.SetDeltaSkinning(batch.delta_skinning());
        coarse.SetRays(rays);
        coarse.EvaluateAll(false);
        for (int r = 0; r < coarse.num_rays(); ++r) {
          ImportanceResample(coarse.evaluation(r).tau, &rays[r].samples, &state->rng);
        }
      }
      Eigen::Matrix3Xd grid(3, stage.sampling.match_grid_points);
      std::uniform_real_distribution<double> unit(0.0, 1.0);
      for (int i = 0; i < grid.cols(); ++i) {
        for (int k = 0; k < 3; ++k) {
          grid(k, i) = bounds_.min()[k] + unit(state->rng) * bounds_.sizes()[k];
        }
      }
      batch.SetMatchGrid(grid);
      batch.SetRays(std::move(rays));
      std::set<const double*> used;
      for (int r = 0; r < batch.num_rays(); ++r) {
        for (int t = 0; t < kNumLossTerms; ++t) {
          const LossTerm term = static_cast<LossTerm>(t);
          if (!batch.rays()[r].HasTerm(term, batch_options.weights)) continue;
          std::vector<double*> blocks = batch.TermParameterBlocks(r, term);
          used.insert(blocks.begin(), blocks.end());
          batch_blocks.push_back(problem.AddResidualBlock(batch.MakeCostFunction(r, term).release(),
                                                          robust[t].get(), blocks));
        }
      }
      if (stage.losses.eikonal.weight > 0 && stage.sampling.eikonal_points > 0) {
        Eigen::Matrix3Xd points(3, stage.sampling.eikonal_points);
        for (int i = 0; i < points.cols(); ++i) {
          for (int k = 0; k < 3; ++k) {
            points(k, i) = bounds_.min()[k] + unit(state->rng) * bounds_.sizes()[k];
          }
        }
        batch_blocks.push_back(problem.AddResidualBlock(
            MakeEikonalCostFunction(model.field(), points, stage.losses.eikonal.weight).release(),
            eikonal_robust.get(), model.sdf()));
        regularizer_blocks.push_back(batch_blocks.back());
      }
      if (B > 0 && stage.losses.bone_inside.weight > 0) {
        batch_blocks.push_back(problem.AddResidualBlock(
            MakeBoneInsideCostFunction(model.field(), B, stage.losses.bone_inside_margin,
                                       stage.losses.bone_inside.weight)
                .release(),
            inside_robust.get(), model.sdf(), model.bones()));
        regularizer_blocks.push_back(batch_blocks.back());
      }
      if (stage.losses.pose_smoothness.weight > 0) {
        std::set<std::pair<int, int>> frames;
        for (const Ray& ray : batch.rays()) frames.insert({ray.video, ray.frame});
        const double w = stage.losses.pose_smoothness.weight;
        for (const auto& [v, t] : frames) {
          if (t + 1 >= static_cast<int>(model.video(v).frames.size())) continue;
          FrameParameters& a = model.frame(v, t);
          FrameParameters& b = model.frame(v, t + 1);
          batch_blocks.push_back(problem.AddResidualBlock(
              MakeRootSmoothnessCostFunction(a.root_init, b.root_init, w, w).release(),
              smooth_robust.get(), a.root_delta.data(), b.root_delta.data()));
          regularizer_blocks.push_back(batch_blocks.back());
          used.insert(b.root_delta.data());
          if (B > 0) {
            batch_blocks.push_back(
                problem.AddResidualBlock(MakeBoneSmoothnessCostFunction(B, w, w).release(),
                                         smooth_robust.get(), a.bones_t.data(), b.bones_t.data()));
            regularizer_blocks.push_back(batch_blocks.back());
            used.insert(b.bones_t.data());
          }
        }
      }
      used.insert(model.sdf());
      if (B > 0) used.insert(model.bones());

      // ---- The step. ----
      auto free_blocks = [&](const std::set<std::string>& only) {
        std::vector<double*> out;
        for (const auto& [group, blocks] : groups) {
          if (constant.count(group) || (!only.empty() && !only.count(group))) continue;
          for (double* p : blocks) {
            if (used.count(p)) out.push_back(p);
          }
        }
        return out;
      };
      // after_gradient (optional) runs once the gradient is known and before
      // the update, when the batch's value cache holds the residuals at the
      // step's starting point.
      auto adam_step = [&](const std::vector<double*>& blocks,
                           const std::function<void()>& after_gradient) {
        if (blocks.empty()) {
          if (after_gradient) {
            batch.EvaluateAll(false);
            after_gradient();
          }
          return;
        }
        // The gradient of the cost in the tangent space of each block, in
        // the order of `blocks`.
        std::vector<double> gradient;
        if (options.adam_gradient_from_ceres) {
          ceres::Problem::EvaluateOptions eo;
          eo.parameter_blocks = blocks;
          // Our cost functions only copy from the batch's cache; one thread
          // keeps Ceres' gradient sums in a fixed order (bitwise-reproducible
          // resume).
          eo.num_threads = 1;
          double cost = 0.0;
          CHECK(problem.Evaluate(eo, &cost, nullptr, &gradient, nullptr));
        } else {
          // Ray terms without their Jacobians (one cotangent row per ray),
          // the regularisers from their cost functions; all sums in a fixed
          // order (bitwise-reproducible resume).
          std::map<const double*, Eigen::VectorXd> ambient;
          batch.EvaluateGradient(ray_robust, &ambient);
          for (ceres::ResidualBlockId id : regularizer_blocks) {
            AddResidualBlockGradient(problem, id, &ambient);
          }
          for (double* p : blocks) {
            const ceres::Manifold* manifold = problem.GetManifold(p);
            const int size = problem.ParameterBlockSize(p);
            const int tangent = manifold != nullptr ? manifold->TangentSize() : size;
            const auto found = ambient.find(p);
            if (found == ambient.end()) {  // no residual reads it
              gradient.insert(gradient.end(), tangent, 0.0);
              continue;
            }
            const Eigen::VectorXd& g = found->second;
            CHECK_EQ(g.size(), size);
            if (manifold == nullptr) {
              gradient.insert(gradient.end(), g.data(), g.data() + size);
              continue;
            }
            // g_tangent = PlusJacobian(x)^T g_ambient (chain rule through
            // x + delta at delta = 0, as Ceres does).
            RowMajorMatrix plus(size, tangent);
            CHECK(manifold->PlusJacobian(p, plus.data()));
            const Eigen::VectorXd gt = plus.transpose() * g;
            gradient.insert(gradient.end(), gt.data(), gt.data() + tangent);
          }
        }
        if (after_gradient) {
          CHECK(batch.cache_valid());
          after_gradient();
        }
        const AdamConfig& a = stage.adam;
        const double lr = LearningRate(a, it, stage.iterations);
        size_t offset = 0;
        for (double* p : blocks) {
          const ceres::Manifold* manifold = problem.GetManifold(p);
          const int size = problem.ParameterBlockSize(p);
          const int tangent = manifold != nullptr ? manifold->TangentSize() : size;
          const std::string& name = block_names.at(p);
          State::Moments& mo = state->adam[name];
          if (mo.m.empty()) {
            mo.m.assign(tangent, 0.0);
            mo.v.assign(tangent, 0.0);
          }
          ++mo.steps;
          const bool is_mlp =
              name == "sdf" || name == "color" || name == "embedding" || name == "delta_skinning";
          double scale = 1.0;
          if (name.find("root_delta") != std::string::npos) scale = a.pose_lr_scale;
          if (name == "bones" || name.find("bones_t") != std::string::npos) scale = a.bone_lr_scale;
          const double bc1 = 1.0 - std::pow(a.beta1, mo.steps);
          const double bc2 = 1.0 - std::pow(a.beta2, mo.steps);
          std::vector<double> delta(tangent);
          for (int k = 0; k < tangent; ++k) {
            const double g = gradient[offset + k];
            mo.m[k] = a.beta1 * mo.m[k] + (1.0 - a.beta1) * g;
            mo.v[k] = a.beta2 * mo.v[k] + (1.0 - a.beta2) * g * g;
            delta[k] = -lr * scale * (mo.m[k] / bc1) / (std::sqrt(mo.v[k] / bc2) + a.epsilon);
          }
          if (is_mlp && a.weight_decay > 0) {
            for (int k = 0; k < size; ++k) p[k] -= lr * a.weight_decay * p[k];
          }
          if (manifold != nullptr) {
            std::vector<double> moved(size);
            CHECK(manifold->Plus(p, delta.data(), moved.data()));
            std::copy(moved.begin(), moved.end(), p);
          } else {
            for (int k = 0; k < size; ++k) p[k] += delta[k];
          }
          offset += tangent;
        }
        CHECK_EQ(offset, gradient.size());
        batch.Invalidate();
      };
      auto lm_step = [&](const std::set<std::string>& hold) {
        std::vector<double*> held;
        for (const std::string& g : hold) {
          if (constant.count(g)) continue;
          for (double* p : groups[g]) {
            problem.SetParameterBlockConstant(p);
            held.push_back(p);
          }
        }
        ceres::Solver::Options so;
        so.minimizer_type = ceres::TRUST_REGION;
        so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
        so.linear_solver_type =
            stage.lm.linear_solver == "iterative_schur" ? ceres::ITERATIVE_SCHUR : ceres::CGNR;
        so.preconditioner_type =
            stage.lm.linear_solver == "iterative_schur" ? ceres::SCHUR_JACOBI : ceres::IDENTITY;
        so.max_linear_solver_iterations = stage.lm.max_cg_iterations;
        so.min_linear_solver_iterations = 1;
        so.max_num_iterations = stage.lm.iterations_per_batch;
        so.initial_trust_region_radius =
            state->lm_radius > 0 ? state->lm_radius : stage.lm.initial_radius;
        so.max_trust_region_radius = stage.lm.max_radius;
        so.num_threads = 1;  // as for Evaluate: the heavy work is in RayBatch
        so.logging_type = ceres::SILENT;
        so.minimizer_progress_to_stdout = false;
        so.update_state_every_iteration = true;
        ceres::Solver::Summary sum;
        ceres::Solve(so, &problem, &sum);
        if (!sum.iterations.empty()) {
          state->lm_radius =
              std::min(sum.iterations.back().trust_region_radius, stage.lm.max_radius);
        }
        for (double* p : held) problem.SetParameterBlockVariable(p);
        batch.Invalidate();
      };

      // Losses at the batch's starting point, for progress and active
      // sampling, from the batch's value cache (Adam: filled by its gradient
      // evaluation, so no extra forward pass).
      TermLosses losses;
      std::vector<double> errors(batch.num_rays(), 0.0);
      auto record_losses = [&] {
        for (int r = 0; r < batch.num_rays(); ++r) {
          const RayEvaluation& ev = batch.evaluation(r);
          const int n = batch.rays()[r].NumSamples();
          for (int t = 0; t < kNumLossTerms; ++t) {
            if (ev.term_row[t] < 0) continue;
            const LossTerm term = static_cast<LossTerm>(t);
            double sq = 0.0;
            for (int k = 0; k < LossTermResiduals(term, n); ++k) {
              sq += ev.residuals[ev.term_row[t] + k] * ev.residuals[ev.term_row[t] + k];
            }
            losses[LossTermName(term)] += 0.5 * sq / batch.num_rays();
            if (term == LossTerm::kRgb || term == LossTerm::kSilhouette) errors[r] += sq;
          }
        }
        sampler.RecordErrors(batch.rays(), errors);
      };

      if (stage.step_rule == "adam") {
        adam_step(free_blocks({}), record_losses);
      } else {
        batch.EvaluateAll(false);
        record_losses();
        if (stage.step_rule == "lm") {
          lm_step({});
        } else {  // alternate
          // Fields and codes by Adam (MLP_Delta and its pose codes are
          // fields), then the coupled poses and bones by LM.
          const std::set<std::string> fields = {
              "sdf", "color", "embedding", "log_beta", "appearance", "delta_skinning", "pose_code"};
          adam_step(free_blocks(fields), nullptr);
          lm_step(fields);
        }
      }

      // Set constancy back (lm_step's hold toggled variable blocks).
      for (const std::string& g : constant) {
        for (double* p : groups[g]) problem.SetParameterBlockConstant(p);
      }

      rays_done += batch.num_rays();
      ++state->total_batches;
      if (it == start) summary.first_losses = losses;
      summary.last_losses = losses;
      const bool last = it + 1 == stage.iterations;
      if (!options.quiet && (it % std::max(1, stage.log_every) == 0 || last)) {
        const double secs = stage_seconds();
        const double rate = rays_done / std::max(secs, 1e-9);
        const double eta = (stage.iterations - it - 1) * stage.batch_rays / std::max(rate, 1e-9);
        std::printf("[%s] %5d/%d", stage.name.c_str(), it + 1, stage.iterations);
        double total = 0.0;
        for (const auto& [name, value] : losses) {
          std::printf(" %s=%.4g", name.c_str(), value);
          total += value;
        }
        std::printf(" | total=%.4g | %.0f rays/s | ETA %.0fs\n", total, rate, eta);
        std::fflush(stdout);
      }
      if (stage.checkpoint_every > 0 && (it + 1) % stage.checkpoint_every == 0 && !last) {
        save(s, it + 1);
      }
      if (options.on_batch) {
        Timer callback_timer;
        BatchProgress progress;
        progress.stage = s;
        progress.stage_name = stage.name;
        progress.iteration = it + 1;
        progress.stage_iterations = stage.iterations;
        progress.total_batches = state->total_batches;
        progress.solve_seconds = run_timer.Seconds() - callback_seconds;
        progress.losses = losses;
        options.on_batch(progress, model);
        callback_seconds += callback_timer.Seconds();
      }
    }
    for (ceres::ResidualBlockId id : batch_blocks) problem.RemoveResidualBlock(id);
    summary.iterations = stage.iterations - start;
    summary.seconds = stage_seconds();
    summary.rays_per_second = rays_done / std::max(summary.seconds, 1e-9);
    model.ForEachBlock([&](const std::string&, double* data, int size) {
      for (int k = 0; k < size; ++k) summary.finite = summary.finite && std::isfinite(data[k]);
    });
    result.stages.push_back(summary);
    state->iteration = 0;
    save(s + 1, 0);
    if (!options.quiet) {
      std::printf("[%s] done: %d batches in %.1f s (%.0f rays/s)%s\n", stage.name.c_str(),
                  summary.iterations, summary.seconds, summary.rays_per_second,
                  summary.finite ? "" : " -- NON-FINITE PARAMETERS");
      std::fflush(stdout);
    }
  }
  return result;
}

}  // namespace banmo

namespace banmo {

void Solver::RefreshBounds() { bounds_ = CanonicalBoundsFromSurface(*model_, bounds_); }

void Solver::ReinitializeBones(State* state) {
  Model& model = *model_;
  const int B = model.num_bones();
  ExtractOptions options;
  options.grid.resolution = 48;
  options.grid.bounds_min = bounds_.min();
  options.grid.bounds_max = bounds_.max();
  TriangleMesh mesh;
  try {
    mesh = ExtractCanonicalMesh(model, options);
  } catch (const InputError&) {
    return;  // no surface yet: keep the bones
  }
  if (mesh.NumVertices() < B) return;
  const std::vector<Eigen::Vector3d> centres =
      BoneCentresFromSurface(mesh, B, static_cast<uint32_t>(state->rng()));
  InitializeBones(centres, model.options().init_bone_scale, model.bones());
  for (int v = 0; v < model.num_videos(); ++v) {
    for (size_t t = 0; t < model.video(v).frames.size(); ++t) {
      double* bones_t = model.frame(v, t).bones_t.data();
      for (int b = 0; b < B; ++b) PoseSetIdentity(bones_t + kPoseSize * b);
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
  for (auto it = state->adam.begin(); it != state->adam.end();) {
    const bool bone = it->first == "bones" || it->first.find("bones_t") != std::string::npos ||
                      it->first == "delta_skinning";
    it = bone ? state->adam.erase(it) : std::next(it);
  }
}

}  // namespace banmo
