#include "solve_outputs.h"

#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <filesystem>

#include "banmo/eval/evaluate.h"
#include "banmo/eval/mesh_sequence.h"
#include "banmo/eval/report.h"
#include "banmo/extract/extract.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/timer.h"
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
  if (resume && std::filesystem::exists(path)) {
    int recorded = 0;
    try {
      recorded = YAML::LoadFile(path)["every"].as<int>();
    } catch (const YAML::Exception& e) {
      ThrowInputError(path, ": expected 'every: N' (an integer), ", e.what());
    }
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
  options.frame.jitter_passes = 4;  // as banmo render: the expected rendering the losses fit
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

}  // namespace banmo
