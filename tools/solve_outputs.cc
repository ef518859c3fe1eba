#include "solve_outputs.h"

#include <cstdio>

#include "banmo/eval/evaluate.h"
#include "banmo/eval/mesh_sequence.h"
#include "banmo/eval/report.h"
#include "banmo/extract/extract.h"
#include "banmo/util/timer.h"

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

}  // namespace banmo
