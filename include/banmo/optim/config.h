// Solver configuration: the model's sizes and a list of stages (docs/config.md,
// docs/solver.md), read from YAML files in problems/. YAML keys equal the struct
// field names below; an unknown key, a wrong type or a violated constraint is
// an InputError naming the file, the key path (e.g. "stages[1].adam.lr") and
// what was expected. The resolved configuration (every default filled in) is
// written next to the outputs of every run.
#pragma once

#include <array>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "banmo/losses/ray.h"
#include "banmo/model/model.h"
#include "banmo/model/parameter_group.h"
#include "banmo/registration/bone_registration_config.h"
#include "banmo/util/enum_names.h"
#include "banmo/util/option_check.h"

namespace banmo {

// Typed options: each is read from its YAML name in one place
// (util/enum_names.h); an unknown name is an error listing the choices.
enum class StepRule { kAdam, kLm, kAlternate };
enum class LinearSolverType { kCgnr, kIterativeSchur };
enum class LrSchedule { kOneCycle, kConstant };
enum class RobustLossType { kNone, kHuber, kCauchy, kSoftL1, kArctan, kTolerant };
enum class BoneSites { kSurface, kSkeleton };

template <>
struct EnumNames<StepRule> {
  static constexpr std::pair<StepRule, const char*> kNames[] = {
      {StepRule::kAdam, "adam"}, {StepRule::kLm, "lm"}, {StepRule::kAlternate, "alternate"}};
};
template <>
struct EnumNames<LinearSolverType> {
  static constexpr std::pair<LinearSolverType, const char*> kNames[] = {
      {LinearSolverType::kCgnr, "cgnr"}, {LinearSolverType::kIterativeSchur, "iterative_schur"}};
};
template <>
struct EnumNames<LrSchedule> {
  static constexpr std::pair<LrSchedule, const char*> kNames[] = {
      {LrSchedule::kOneCycle, "onecycle"}, {LrSchedule::kConstant, "constant"}};
};
template <>
struct EnumNames<RobustLossType> {
  static constexpr std::pair<RobustLossType, const char*> kNames[] = {
      {RobustLossType::kNone, "none"},     {RobustLossType::kHuber, "huber"},
      {RobustLossType::kCauchy, "cauchy"}, {RobustLossType::kSoftL1, "soft_l1"},
      {RobustLossType::kArctan, "arctan"}, {RobustLossType::kTolerant, "tolerant"}};
};

template <>
struct EnumNames<BoneSites> {
  static constexpr std::pair<BoneSites, const char*> kNames[] = {
      {BoneSites::kSurface, "surface"}, {BoneSites::kSkeleton, "skeleton"}};
};

// Robust loss applied to one loss term's residual block (Ceres LossFunction).
struct RobustLossConfig {
  RobustLossType type = RobustLossType::kNone;
  double scale = 1.0;  // the loss's scale parameter a (> 0)
};

// One loss term: weight (0 = off) and robust loss.
struct LossConfig {
  double weight = 0.0;
  RobustLossConfig robust;

  // Each Check(c, key) below checks the struct's own fields, `key` its key
  // path (e.g. "stages[1].adam"); InputError naming the file and the key
  // (util/option_check.h).
  void Check(const OptionChecker& c, const std::string& key) const;
};

// Every loss term's weight and robust loss, indexed by LossTerm; the YAML
// keys and default weights come from the loss table (losses/loss_table.h).
struct LossesConfig {
  LossesConfig();
  std::array<LossConfig, kNumLossTerms> terms;
  double bone_inside_margin = 0.02;  // canonical units
  // The rendered-embedding term trains the embedding only
  // (RayBatchOptions::feature_render_embedding_only).
  bool feature_render_embedding_only = false;

  LossConfig& operator[](LossTerm term) { return terms.at(static_cast<size_t>(term)); }
  const LossConfig& operator[](LossTerm term) const { return terms.at(static_cast<size_t>(term)); }
  // The per-ray terms' weights.
  RayLossWeights RayWeights() const;
  void Check(const OptionChecker& c, const std::string& key) const;
};

struct AdamConfig {
  double lr = 5e-4;  // peak learning rate
  double beta1 = 0.9;
  double beta2 = 0.999;
  double epsilon = 1e-8;
  double weight_decay = 0.0;  // AdamW decoupled decay, MLP weights only
  LrSchedule schedule = LrSchedule::kOneCycle;
  double warmup_fraction = 0.1;     // one-cycle: fraction of iterations rising to lr
  double final_lr_fraction = 0.01;  // one-cycle: lr at the end / lr
  // Per-group learning-rate multipliers (pose blocks like a larger step).
  double pose_lr_scale = 1.0;
  double bone_lr_scale = 1.0;
  // VolSDF's log beta: Adam moves a coordinate by about lr a step, so at
  // lr 2e-3 beta can shrink by at most a factor of about 2 over a stage.
  double beta_lr_scale = 1.0;
  // The intrinsics [fx, fy, cx, cy] are in pixels, so at lr 2e-3 a stage
  // moves a freed focal length (group `intrinsics` not constant) by a few
  // pixels at most; 50 moves it about 0.1 px a batch. On casual renders
  // that did not recover a wrong focal length (benchmarks/log/2026-12.md).
  double intrinsics_lr_scale = 1.0;
  // Temporal bases of the per-frame steps (docs/solver.md, "Temporal step
  // bases"): with K > 0, Adam steps each video's bone transforms (root
  // corrections) in the coefficients of K cosines over the video's frames
  // (min(K, frames); K >= frames is a complete basis), so every batch moves
  // every frame of the videos it samples. 0: each frame's block on its own.
  int bone_basis = 0;
  int root_basis = 0;

  void Check(const OptionChecker& c, const std::string& key) const;
};

struct LmConfig {
  int max_cg_iterations = 15;   // CGNR iterations per LM step
  double initial_radius = 1e3;  // Ceres initial trust-region radius
  double max_radius = 1e6;      // cap of the radius carried between batches
  LinearSolverType linear_solver = LinearSolverType::kCgnr;
  int iterations_per_batch = 1;  // LM iterations on one minibatch

  void Check(const OptionChecker& c, const std::string& key) const;
};

struct SamplingConfig {
  double foreground_fraction = 0.5;  // fraction of rays drawn inside the mask
  // Fraction drawn from the pixels within RaySampler::kBoundaryBandPx of
  // the mask's edge (object pixels with a background pixel that near, and
  // background pixels with an object pixel that near), where the fitted
  // silhouette's errors sit; foreground_fraction + boundary_fraction <= 1.
  double boundary_fraction = 0.0;
  double active_fraction = 0.0;  // fraction drawn from the error cache (active sampling)
  // The rays drawn uniformly (neither in the mask nor in the edge band) come
  // from the bounding box of the frame's mask scaled by crop_scale about its
  // centre (RaySampler::CropRect); 0: from the whole image.
  double crop_scale = 0.0;
  bool importance_depth = false;  // second pass of samples around the surface
  // With importance_depth: 0 redraws half of the samples_per_ray samples from
  // the first pass's weights (a ray keeps samples_per_ray samples); K > 0
  // keeps all of them and adds K drawn ones (NeRF's coarse + fine; the paper
  // 64 + 64). ImportanceResample (volume/ray_samples.h).
  int importance_samples = 0;
  // With importance_depth: the importance pass also puts a sample at each
  // ray's SDF minimum (the vertex of a parabola through the first pass's
  // smallest SDF sample and its neighbours) in place of one drawn sample.
  // NeuS's opacity of a ray is 1 - Phi(f_min) / Phi(f_0): a ray that
  // grazes a thin part renders it only if a sample lands near f_min.
  // ImportanceResample (volume/ray_samples.h).
  bool min_sdf_sample = false;
  double near_far_margin = 0.2;  // +-20 % around the canonical bounds' depth range
  // Each ray's samples span only its part inside the canonical bounds
  // widened by clip_margin times their largest side (ClipDepthsToBox,
  // volume/ray_samples.h), not the frame's whole near-far range.
  bool clip_to_box = false;
  double clip_margin = 0.1;
  std::vector<int> flow_gaps = {1, 2, 4, 8};  // frame gaps used by the flow term
  int eikonal_points = 256;                   // canonical points per batch for the eikonal term
  int match_grid_points = 4096;               // canonical grid of the soft-argmax
  int match_top_k = 32;                       // K of the truncated soft-argmax
  // Frames a batch's (non-active) rays are drawn from: that many distinct
  // frames at random, the rays spread evenly over them (0 = every ray from
  // a frame of its own draw).
  int frames_per_batch = 0;
  // The silhouette residual of each ray is weighted by its pixel's
  // importance weight (RaySampler::PixelWeight): the loss is then an
  // unbiased estimate of the mean over all pixels instead of favouring
  // the object pixels the sampler draws more often.
  bool unbiased_silhouette = false;

  void Check(const OptionChecker& c, const std::string& key) const;
};

struct ScheduleConfig {
  std::vector<double> bone_reinit_at;  // fractions of the stage at which bones are re-initialised
  // A re-initialisation hands each frame's motion to the new bones
  // (TransferBoneMotion, deform/bones.h) instead of resetting it.
  bool bone_reinit_keep_motion = false;
  // Where a re-initialisation puts the bone centres: k-means of the coarse
  // surface (area-weighted), or of its mean-curvature-flow curve skeleton
  // (length-weighted), which gives limbs bones in proportion to their
  // length instead of their area (extract/skeleton.h).
  BoneSites bone_sites = BoneSites::kSurface;
  // For this fraction of the stage after each re-initialisation the shape,
  // appearance and root poses (groups sdf, color, embedding, log_beta,
  // appearance, root) are held constant, so the new bones take up the
  // motion before the density spreads to explain it (the official BANMo
  // code freezes them for 1 % of training). 0 = off.
  double freeze_after_reinit = 0.0;
  int bounds_refresh_every = 0;  // batches between canonical-bounds refreshes (0 = never)
  // The largest fraction of the masks' object pixels a refresh may leave
  // outside the box their rays meet (optim/bounds_refresh.h): a box that
  // loses more stays nearer the old one. A model that breaks up for a while
  // loses most (the box shrinks onto one fragment); a shape that forms loses
  // none (docs/solver.md, "Canonical bounds"). >= 1: no check.
  double bounds_refresh_max_mask_loss = 0.05;
  double anneal_end_fraction = 0.0;  // coarse-to-fine PE annealing reaches all bands here (0 = off)
  double delta_skinning_from = 1.0;  // fraction from which delta skinning is free (>= 1: never)
  // Fraction of the stage from which the root corrections are free; before
  // it they are held constant, so the shape first forms in the initial
  // root poses (0: free from the start).
  double root_free_from = 0.0;
  // Fraction of the stage from which the silhouette residuals carry their
  // pixels' importance weights, as under sampling.unbiased_silhouette
  // (>= 1: never; that key on means from the start).
  double unbiased_silhouette_from = 1.0;
  // Fraction of the stage from which the model renders with NeuS's density
  // instead of VolSDF's (model.density), to the end of the solve: the
  // silhouette then fits the zero level set, without VolSDF's shell
  // (>= 1: never).
  double neus_from = 1.0;

  // `batches`: the stage's (a fraction must fall on one of its batches).
  void Check(const OptionChecker& c, const std::string& key, int batches) const;
};

// Per-frame root-pose solves (docs/solver.md, "Pose solves"): at the given
// fractions of the stage, every frame's root pose by Levenberg-Marquardt on
// `rays` rays of that frame with the fields held constant; frames whose cost
// stays high try a multi-hypothesis search.
struct PoseSolveConfig {
  std::vector<double> at;  // fractions of the stage (increasing, in [0, 1]; empty = never)
  // Also every `every` batches (before batches every, 2 every, ...; 0 =
  // never). The `alternate` step rule moves the per-frame root corrections
  // (and with `bones` the bone transforms) only in these solves.
  int every = 0;
  int rays = 256;       // rays per frame, sampling.foreground_fraction of them in the mask
  int iterations = 10;  // LM iterations per frame and per hypothesis
  // A frame whose cost per ray after its solve exceeds search_ratio times
  // the median frame's runs the search (0 = never).
  double search_ratio = 0.0;
  int search_rotations = 72;  // candidate rotations of the search (a uniform SO(3) set)
  int search_keep = 3;        // the candidates of lowest cost refined by LM
  // Also solve each frame's bone transforms J_b^t (with its root correction,
  // or alone when the stage holds the root constant); in an `alternate`
  // stage the bone transforms then move only in the solves.
  bool bones = false;
  // Only on a dataset without pixel features (footage prepared from frames
  // and masks), whose roots no feature registration has placed.
  bool featureless_only = false;

  void Check(const OptionChecker& c, const std::string& key, int batches) const;
};

// Parameter groups held constant (ceres SetParameterBlockConstant):
// model/parameter_group.h, docs/config.md.
struct StageConfig {
  std::string name = "stage";
  int batches = 100;  // minibatches of the stage (its steps; config key `batches`)
  // The batch at which a schedule's fraction of the stage fires.
  int BatchAt(double fraction) const { return static_cast<int>(std::lround(fraction * batches)); }
  StepRule step_rule = StepRule::kAdam;
  int batch_rays = 1024;
  int samples_per_ray = 32;
  LossesConfig losses;
  std::vector<ParameterGroup> constant = {ParameterGroup::kIntrinsics};
  AdamConfig adam;
  LmConfig lm;
  SamplingConfig sampling;
  ScheduleConfig schedule;
  PoseSolveConfig pose_solve;
  BoneRegistrationConfig bone_registration;
  // Steps of the bone transforms J_b^t turn each about its bone's centre
  // (MakeStackedPivotPoseManifold, geometry/pose_manifold.h) instead of
  // about the canonical origin; Adam and the pose solves alike.
  bool bone_steps_about_centres = false;
  // Steps of a frame's bone transforms follow the rest bones' joint tree
  // (MakeArticulatedBoneManifold, deform/articulated_manifold.h): the root
  // bone's rigid step and one turn per other bone about its joint with its
  // parent, carrying its subtree (3 B + 3 unknowns a frame instead of 6 B),
  // so no step slides a bone away from its neighbours. Adam and the lm /
  // alternate step rules; the pose solves keep their own steps.
  bool bone_steps_articulated = false;
  int checkpoint_every = 0;  // batches between checkpoints (0 = end of stage only)
  int log_every = 10;        // batches between progress lines

  // Its sections' Check()s, then the rules that span several of them
  // (constant groups against pose solves and registrations, ...).
  void Check(const OptionChecker& c, const std::string& key) const;
};

// The stage's sampling at `fraction` of it: sampling.unbiased_silhouette is
// on from schedule.unbiased_silhouette_from. The minibatches use it; the pose
// solves keep the stage's own sampling.
SamplingConfig SamplingAt(const StageConfig& stage, double fraction);

struct SolverConfig {
  ModelOptions model;  // model.field.* = CanonicalFieldOptions fields
  std::vector<StageConfig> stages;
  uint32_t seed = 0;
  int threads = 0;  // 0 = all hardware threads
};

// Reads and validates a config file. Throws InputError naming the file and key.
SolverConfig LoadSolverConfig(const std::string& path);
// Parses YAML text (`source` names it in errors).
SolverConfig ParseSolverConfig(const std::string& yaml_text, const std::string& source);
// The resolved configuration as YAML (every field, defaults filled in); parsing
// it again gives the same config.
std::string SolverConfigToYaml(const SolverConfig& config);
// Throws InputError on a violated constraint (source names the file).
void CheckSolverConfig(const SolverConfig& config, const std::string& source);

}  // namespace banmo
