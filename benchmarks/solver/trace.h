// Speed-against-error traces of the solver: config overrides on the
// command line, finiteness checks of a model, and the trace CSV. Used by
// banmo_trace (trace_main.cc); benchmarks/solver/README.md has the whole
// harness.
#pragma once

#include <limits>
#include <map>
#include <string>
#include <vector>

#include "banmo/model/model.h"
#include "banmo/optim/config.h"

namespace banmo::bench {

// Applies "path=value" overrides to a config's YAML text and parses the
// result with ParseSolverConfig (so every key is checked as in a config
// file). Paths are dot-separated keys; a list element is key[i], and key[*]
// applies to every element of the list (e.g. "stages[*].step_rule=lm",
// "model.num_bones=4", "stages[0].batches=200",
// "stages[*].sampling.flow_gaps=[8]"). Missing maps on the way are created;
// an unknown key is then reported by the config parser. The value is parsed
// as YAML (numbers, booleans, lists, maps). Throws InputError naming
// `source` and the override on a malformed path or value.
SolverConfig ParseConfigWithOverrides(const std::string& yaml_text,
                                      const std::vector<std::string>& overrides,
                                      const std::string& source);

// The YAML text of `yaml_text` with the overrides applied (for the resolved
// config and for tests).
std::string ApplyOverrides(const std::string& yaml_text, const std::vector<std::string>& overrides,
                           const std::string& source);

// Name of the first parameter block of `model` holding a NaN or Inf (e.g.
// "sdf", "video1/frame3/root_delta"), or "" if every parameter is finite.
// Blocks in Model::ForEachBlock order (G0^t data included, it must be finite too).
std::string FirstNonFiniteBlock(const Model& model);

// One row of the trace CSV.
struct TraceRow {
  std::string config;          // named configuration
  std::string scene;           // named scene
  std::string kind;            // "trace" (checkpoint), "final" (full-resolution), "nonfinite"
  int stage = -1;              // stage index (-1: before the first batch)
  std::string stage_name;      //
  int batch = 0;               // batches done in the stage
  int total_batches = 0;       // batches done in all stages
  double solve_seconds = 0.0;  // solver wall time without the trace's own time
  double cpu_seconds = 0.0;    // user + system CPU time of the process so far
  double wall_seconds = 0.0;   // process wall time so far (includes the trace's evaluations)
  double trace_seconds = 0.0;  // time spent in trace evaluations so far
  std::map<std::string, double> losses;  // the batch's per-term losses (ray terms)
  bool params_finite = true;
  bool losses_finite = true;
  std::string nonfinite_what;    // first non-finite block or loss term
  int resolution = 0;            // marching-cubes resolution of the evaluated mesh
  int mesh_vertices = 0;         // canonical mesh vertices (0: empty level set)
  int eval_frames = 0;           // frames evaluated
  double chamfer_cm = 0.0;       // banmo protocol (NaN if the mesh is empty)
  double fscore[3] = {0, 0, 0};  // F@1 %, F@2 %, F@5 % in percent
  // Root rotation error against the dataset's ground-truth poses, mean and
  // 90th percentile in degrees (registration/root_pose_error.h; NaN without them).
  double root_rot_mean_deg = std::numeric_limits<double>::quiet_NaN();
  double root_rot_p90_deg = std::numeric_limits<double>::quiet_NaN();
};

// Ray loss terms in CSV column order (loss_<term>).
const std::vector<std::string>& TraceLossTerms();
// CSV header line (with '\n').
std::string TraceCsvHeader();
// CSV line of one row (with '\n'); numbers with 6-9 significant digits, NaN as "nan".
std::string TraceCsvLine(const TraceRow& row);

// User + system CPU seconds of this process (getrusage).
double ProcessCpuSeconds();

}  // namespace banmo::bench
