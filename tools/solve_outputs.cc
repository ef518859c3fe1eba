#include "solve_outputs.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "banmo/eval/evaluate.h"
#include "banmo/eval/mesh_sequence.h"
#include "banmo/eval/report.h"
#include "banmo/extract/extract.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"
#include "banmo/util/timer.h"
#include "banmo/util/yaml.h"
#include "banmo/visualize/holdout.h"
#include "banmo/visualize/render.h"

namespace banmo {

void WriteSolveOutputs(const Model& model, const Dataset& dataset, const std::string& out_dir,
                       int resolution, bool evaluate) {
  Timer timer;
  ExtractOptions extract;
  extract.grid.resolution = resolution;
  const Eigen::AlignedBox3d box = ExtractionBounds(model);  // the trained box
  extract.grid.bounds_min = box.min();
  extract.grid.bounds_max = box.max();
  const ExtractionSummary s = WriteExtraction(model, extract, out_dir + "/meshes");
  std::printf("meshes: canonical %d vertices / %d faces, %d frame meshes in %s/meshes (%.1f s)\n",
              s.canonical_vertices, s.canonical_faces, s.frames_written, out_dir.c_str(),
              timer.Seconds());
  if (!evaluate) return;
  std::vector<std::string> gt_files;
  for (const Video& video : dataset.videos) {
    if (!video.present.gt_mesh) {
      std::printf("no ground-truth meshes in the dataset: evaluation skipped\n");
      return;
    }
    for (const Frame& frame : video.frames) gt_files.push_back(frame.gt_mesh_path);
  }
  const std::vector<std::string> pred_files = ListMeshFiles(out_dir + "/meshes/frames");
  // The banmo protocol against the dense ground truth (the default,
  // docs/eval.md); `banmo eval --gt-mode vertices` gives the paper's raw
  // vertex protocol.
  EvalOptions options;
  const EvalReport report =
      EvaluateSequence(ReadMeshes(pred_files), ReadMeshes(gt_files), options, pred_files, gt_files);
  std::fputs(FormatReportTable(report).c_str(), stdout);
  WriteEvalOutputs(out_dir + "/eval", report, options);
  std::printf("Chamfer %.2f cm, F@1%% %.1f, F@2%% %.1f, F@5%% %.1f (%zu frames; %s/eval)\n",
              report.chamfer_cm, report.fscore_percent[0], report.fscore_percent[1],
              report.fscore_percent[2], report.frames.size(), out_dir.c_str());
}

int ResolveHoldoutEvery(const std::string& out_dir, bool resume, bool given, int every) {
  const std::string path = out_dir + "/holdout.yaml";
  if (resume && PathExists(path)) {
    int recorded = 0;
    YamlNode::Load(path).ReadRequired("every", &recorded);
    if (given && every != recorded) {
      ThrowInputError("--holdout-every ", every, " with --resume: ", path,
                      " records the solve's --holdout-every ", recorded,
                      " (a resumed solve holds out the same frames); drop the flag");
    }
    return recorded;
  }
  if (resume && given && every != 0) {
    ThrowInputError("--holdout-every ", every, " with --resume: the solve in ", out_dir,
                    " held out no frame (no holdout.yaml); drop the flag");
  }
  return every;
}

void InterpolateHeldOutFramesInCheckpoint(const HoldoutPlan& plan, const std::string& out_dir,
                                          Model* model) {
  InterpolateHeldOutFrames(plan, model);
  CheckpointInfo info;
  std::string state;
  LoadCheckpoint(out_dir + "/checkpoint", &info, &state);
  SaveCheckpoint(out_dir + "/checkpoint", *model, info, state);
}

void WriteHoldoutScore(const Model& model, const Dataset& dataset, const HoldoutPlan& plan,
                       const std::string& out_dir) {
  RenderSequenceOptions options;
  SetTrainedSampling(model, &options.frame);
  // One jittered pass: a quarter of banmo render's default time (4 passes);
  // measured on DAVIS goat frame 10: IoU 0.877 against 0.878 with 4.
  options.frame.jitter_passes = 1;
  options.frame.canonical_bounds = CanonicalBoundsFromSurface(model);
  options.mesh_resolution = 64;  // the mesh panels only
  int height = 1;
  for (const Video& video : dataset.videos) height = std::max(height, video.camera.height);
  options.scale = std::max(1, (256 + height - 1) / height);
  const HoldoutScore score =
      ScoreHeldOutFrames(model, dataset, plan, options, out_dir + "/holdout");
  std::printf(
      "held-out frames (1 in %d, %d frames): mask IoU %.3f mean, %.3f lowest; PSNR %.2f dB "
      "inside the mask (%s/holdout/summary.json; %.1f s)\n",
      plan.every, score.frames, score.mask_iou, score.mask_iou_min, score.psnr, out_dir.c_str(),
      score.seconds);
}

namespace {

std::vector<std::vector<std::string>> ReadCsvRows(const std::string& path,
                                                  std::vector<std::string>* header) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();
    if (first) {
      *header = cells;
      first = false;
    } else {
      rows.push_back(cells);
    }
  }
  return rows;
}

std::string Cell(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", x);
  return buf;
}

}  // namespace

SolveLog::SolveLog(std::string out_dir, bool resume)
    : out_dir_(std::move(out_dir)), resume_(resume) {
  if (!resume_) return;
  // Earlier rows; a damaged or foreign file is dropped (the curves restart).
  std::vector<std::string> header;
  for (const std::vector<std::string>& cells : ReadCsvRows(out_dir_ + "/losses.csv", &header)) {
    if (header.size() < 5 || header[0] != "stage" || cells.size() != header.size()) continue;
    Row row;
    try {
      row.stage = std::stoi(cells[0]);
      row.stage_name = cells[1];
      row.batch = std::stoi(cells[2]);
      row.total_batch = std::stoi(cells[3]);
      row.seconds = std::stod(cells[4]);
      for (size_t c = 5; c < header.size(); ++c) {
        if (header[c] != "total" && !cells[c].empty()) row.losses[header[c]] = std::stod(cells[c]);
      }
    } catch (const std::exception&) {
      continue;
    }
    rows_.push_back(row);
  }
}

void SolveLog::Add(const BatchProgress& progress) {
  if (!trimmed_) {
    // A resume repeats nothing: drop earlier rows from this batch on.
    trimmed_ = true;
    while (!rows_.empty() && rows_.back().total_batch >= progress.total_batches) rows_.pop_back();
    seconds_offset_ = rows_.empty() ? 0.0 : rows_.back().seconds;
  }
  Row row;
  row.stage = progress.stage;
  row.stage_name = progress.stage_name;
  row.batch = progress.batch;
  row.total_batch = progress.total_batches;
  row.seconds = seconds_offset_ + progress.solve_seconds;
  row.losses = progress.losses;
  rows_.push_back(std::move(row));
}

void SolveLog::Write(const SolveResult& result) const {
  std::set<std::string> terms;
  for (const Row& row : rows_) {
    for (const auto& [name, value] : row.losses) terms.insert(name);
  }
  std::ostringstream csv;
  csv << "stage,stage_name,batch,total_batch,seconds";
  for (const std::string& t : terms) csv << "," << t;
  csv << ",total\n";
  for (const Row& row : rows_) {
    csv << row.stage << "," << row.stage_name << "," << row.batch << "," << row.total_batch << ","
        << Cell(row.seconds);
    double total = 0.0;
    for (const std::string& t : terms) {
      const auto it = row.losses.find(t);
      csv << ",";
      if (it != row.losses.end()) {
        csv << Cell(it->second);
        total += it->second;
      }
    }
    csv << "," << Cell(total) << "\n";
  }
  WriteFileAtomic(out_dir_ + "/losses.csv", csv.str());

  // Stages: earlier calls' batches and seconds (resume) plus this call's.
  struct StageTime {
    std::string name;
    int batches = 0;
    double seconds = 0.0, rays = 0.0;
  };
  std::vector<StageTime> stages;
  auto find = [&](const std::string& name) -> StageTime& {
    for (StageTime& s : stages) {
      if (s.name == name) return s;
    }
    stages.push_back(StageTime{name});
    return stages.back();
  };
  if (resume_) {
    std::vector<std::string> header;
    for (const auto& cells : ReadCsvRows(out_dir_ + "/stages.csv", &header)) {
      if (header.size() != 5 || cells.size() != 5 || header[1] != "name") continue;
      try {
        StageTime& s = find(cells[1]);
        s.batches += std::stoi(cells[2]);
        s.seconds += std::stod(cells[3]);
        s.rays += std::stod(cells[4]) * std::stod(cells[3]);
      } catch (const std::exception&) {
        continue;
      }
    }
  }
  for (const StageSummary& r : result.stages) {
    StageTime& s = find(r.name);
    s.batches += r.batches;
    s.seconds += r.seconds;
    s.rays += r.rays_per_second * r.seconds;
  }
  std::ostringstream out;
  out << "stage,name,batches,seconds,rays_per_second\n";
  for (size_t i = 0; i < stages.size(); ++i) {
    const StageTime& s = stages[i];
    out << i << "," << s.name << "," << s.batches << "," << Cell(s.seconds) << ","
        << Cell(s.seconds > 0 ? s.rays / s.seconds : 0.0) << "\n";
  }
  WriteFileAtomic(out_dir_ + "/stages.csv", out.str());
}

}  // namespace banmo
