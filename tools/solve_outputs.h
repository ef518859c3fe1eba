// What `banmo solve` writes after its stages: meshes (banmo extract's files)
// and, when the dataset has ground-truth meshes, their evaluation. Glue
// between library calls only.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "banmo/io/dataset.h"
#include "banmo/io/holdout.h"
#include "banmo/model/model.h"
#include "banmo/optim/solver.h"

namespace banmo {

// Writes OUT/meshes (docs/extract.md) at the given marching-cubes resolution
// within `bounds_min/max`; with `evaluate` and ground truth present, writes
// OUT/eval (docs/eval.md, banmo protocol) and prints the table.
void WriteSolveOutputs(const Model& model, const Dataset& dataset, const std::string& out_dir,
                       int resolution, bool evaluate);

// The --holdout-every of a solve in `out_dir`: the flag's value (0 = none)
// for a new solve, which is recorded in OUT/holdout.yaml; a --resume takes
// the recorded one and refuses another (InputError naming the file).
int ResolveHoldoutEvery(const std::string& out_dir, bool resume, bool given, int every);

// After the stages: the held-out frames get their neighbours' interpolated
// transforms (visualize/holdout.h), also in OUT/checkpoint (so render,
// export and extract show them); their meshes are then what WriteSolveOutputs
// extracts.
void InterpolateHeldOutFramesInCheckpoint(const HoldoutPlan& plan, const std::string& out_dir,
                                          Model* model);

// Renders the held-out frames into OUT/holdout (frames/, errors/,
// frames.csv, summary.json) and prints their mean mask IoU and PSNR.
void WriteHoldoutScore(const Model& model, const Dataset& dataset, const HoldoutPlan& plan,
                       const std::string& out_dir);

// The per-batch losses of a solve and its stages' times, for `banmo report`
// (docs/report.md): OUT/losses.csv (stage, stage_name, batch, total_batch,
// seconds, one column per loss term, total; a cell is empty where a stage
// has no such term) and OUT/stages.csv (stage, name, batches, seconds,
// rays_per_second). Kept in memory and written atomically by Write (after
// the stages, also when interrupted). A resumed solve keeps the rows of
// OUT/losses.csv before its first batch and adds its stages' batches and
// seconds to those of OUT/stages.csv.
class SolveLog {
 public:
  SolveLog(std::string out_dir, bool resume);
  // SolveOptions::on_batch.
  void Add(const BatchProgress& progress);
  void Write(const SolveResult& result) const;

 private:
  struct Row {
    int stage = 0, batch = 0, total_batch = 0;
    std::string stage_name;
    double seconds = 0.0;
    std::map<std::string, double> losses;
  };
  std::string out_dir_;
  bool resume_ = false;
  std::vector<Row> rows_;  // earlier rows (resume) first
  bool trimmed_ = false;   // earlier rows from the resumed batch on dropped
  double seconds_offset_ = 0.0;
};

}  // namespace banmo
