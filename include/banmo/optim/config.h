// Solver configuration: the model's sizes and a list of stages (DESIGN.md
// Sec. 6), read from YAML files in problems/. YAML keys equal the struct
// field names below; an unknown key, a wrong type or a violated constraint is
// an InputError naming the file, the key path (e.g. "stages[1].adam.lr") and
// what was expected. The resolved configuration (every default filled in) is
// written next to the outputs of every run.
#pragma once

#include <string>
#include <vector>

#include "banmo/model/model.h"

namespace banmo {

// Robust loss applied to one loss term's residual block (Ceres LossFunction).
struct RobustLossConfig {
  std::string type = "none";  // none | huber | cauchy | soft_l1 | arctan | tolerant
  double scale = 1.0;         // the loss's scale parameter a (> 0)
};

// One loss term: weight (0 = off) and robust loss.
struct LossConfig {
  double weight = 0.0;
  RobustLossConfig robust;
};

struct LossesConfig {
  LossConfig rgb{1.0, {}};
  LossConfig silhouette{1.0, {}};
  LossConfig flow{0.01, {}};
  LossConfig feature_match{0.1, {}};
  LossConfig cycle_2d{0.001, {}};
  LossConfig cycle_3d{0.1, {}};
  LossConfig eikonal{0.01, {}};
  LossConfig bone_inside{0.1, {}};
  LossConfig pose_smoothness{0.01, {}};  // rotation (rad^2) and translation (units^2) alike
  double bone_inside_margin = 0.02;      // canonical units
};

struct AdamConfig {
  double lr = 5e-4;  // peak learning rate
  double beta1 = 0.9;
  double beta2 = 0.999;
  double epsilon = 1e-8;
  double weight_decay = 0.0;          // AdamW decoupled decay, MLP weights only
  std::string schedule = "onecycle";  // onecycle | constant
  double warmup_fraction = 0.1;       // one-cycle: fraction of iterations rising to lr
  double final_lr_fraction = 0.01;    // one-cycle: lr at the end / lr
  // Per-group learning-rate multipliers (pose blocks like a larger step).
  double pose_lr_scale = 1.0;
  double bone_lr_scale = 1.0;
};

struct LmConfig {
  int max_cg_iterations = 15;          // CGNR iterations per LM step
  double initial_radius = 1e3;         // Ceres initial trust-region radius
  double max_radius = 1e6;             // cap of the radius carried between batches
  std::string linear_solver = "cgnr";  // cgnr | iterative_schur
  int iterations_per_batch = 1;        // LM iterations on one minibatch
};

struct SamplingConfig {
  double foreground_fraction = 0.5;  // fraction of rays drawn inside the mask
  double active_fraction = 0.0;      // fraction drawn from the error cache (active sampling)
  bool importance_depth = false;     // second pass of samples around the surface
  double near_far_margin = 0.2;      // +-20 % around the canonical bounds' depth range
  std::vector<int> flow_gaps = {1, 2, 4, 8};  // frame gaps used by the flow term
  int eikonal_points = 256;                   // canonical points per batch for the eikonal term
  int match_grid_points = 4096;               // canonical grid of the soft-argmax
  int match_top_k = 32;                       // K of the truncated soft-argmax
};

struct ScheduleConfig {
  std::vector<double> bone_reinit_at;  // fractions of the stage at which bones are re-initialised
  int bounds_refresh_every = 0;        // batches between canonical-bounds refreshes (0 = never)
  double anneal_end_fraction = 0.0;  // coarse-to-fine PE annealing reaches all bands here (0 = off)
  double delta_skinning_from = 1.0;  // fraction from which delta skinning is free (>= 1: never)
};

// Parameter groups that can be held constant (ceres SetParameterBlockConstant).
// Names: sdf, color, embedding, log_beta, appearance, root, bones, bones_t, intrinsics,
// delta_skinning, pose_code (docs/config.md).
struct StageConfig {
  std::string name = "stage";
  int iterations = 100;            // minibatches
  std::string step_rule = "adam";  // adam | lm | alternate
  int batch_rays = 1024;
  int samples_per_ray = 32;
  LossesConfig losses;
  std::vector<std::string> constant = {"intrinsics"};
  AdamConfig adam;
  LmConfig lm;
  SamplingConfig sampling;
  ScheduleConfig schedule;
  int checkpoint_every = 0;  // batches between checkpoints (0 = end of stage only)
  int log_every = 10;        // batches between progress lines
};

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
