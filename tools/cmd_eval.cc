// banmo eval: Chamfer distance and F-score of predicted meshes against ground
// truth, in BANMo's protocol or the surface protocol (docs/eval.md).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "banmo/eval/evaluate.h"
#include "banmo/eval/mesh_sequence.h"
#include "banmo/eval/report.h"
#include "banmo/io/dataset.h"
#include "banmo/util/error.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"
#include "command.h"

namespace banmo {
namespace {

// A mesh file, a folder of meshes, or a banmo dataset folder (manifest.yaml,
// docs/dataset.md): then the ground-truth meshes of every video, video by
// video, frame by frame.
std::vector<std::string> ResolveMeshPaths(const std::string& path, const std::string& flag) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec) &&
      std::filesystem::is_regular_file(std::filesystem::path(path) / "manifest.yaml", ec)) {
    LoadOptions load;
    load.load_features = false;
    load.load_flow = false;
    const Dataset dataset = LoadDataset(path, load);
    std::vector<std::string> files;
    for (const Video& video : dataset.videos) {
      if (!video.present.gt_mesh) {
        ThrowInputError(flag, " ", path, ": video '", video.name,
                        "' of the dataset has no ground-truth meshes (gt_mesh/)");
      }
      for (const Frame& frame : video.frames) files.push_back(frame.gt_mesh_path);
    }
    if (files.empty()) ThrowInputError(flag, " ", path, ": dataset has no frames");
    return files;
  }
  return ListMeshFiles(path);
}

int RunEval(int argc, char** argv) {
  CLI::App app{
      "Evaluate predicted meshes against ground truth: ICP alignment, Chamfer distance (cm) and "
      "F-score at 1/2/5 % (docs/eval.md).",
      "banmo eval"};
  std::string pred_path;
  std::string gt_path;
  std::string out_dir;
  std::string protocol = "banmo";
  std::string robust = "none";
  std::string gt_mode = "dense";
  EvalOptions options;
  int threads = 0;
  app.add_option("--pred", pred_path,
                 "Predicted meshes: a .ply/.obj file, or a folder with one mesh per frame "
                 "(sorted by file name)")
      ->required();
  app.add_option("--gt", gt_path,
                 "Ground-truth meshes, same forms as --pred, or a banmo dataset folder "
                 "(manifest.yaml; its gt_mesh/ of every video in order)")
      ->required();
  app.add_option("--protocol", protocol,
                 "banmo (vertices, median-depth scale, rigid ICP: BANMo's script) or surface "
                 "(surface samples, similarity ICP)")
      ->capture_default_str();
  app.add_option("--out", out_dir, "Write per_frame.csv and summary.json into this folder");
  app.add_option("--icp-iterations", options.icp_iterations, "ICP iterations (0 = no ICP)")
      ->capture_default_str();
  app.add_option("--icp-tolerance", options.icp_relative_tolerance,
                 "ICP convergence: relative rmse change below this")
      ->capture_default_str();
  app.add_option("--robust", robust, "Robust ICP: none, trimmed or huber")->capture_default_str();
  app.add_option("--trim-fraction", options.trim_fraction,
                 "Trimmed ICP: fraction of correspondences kept")
      ->capture_default_str();
  app.add_option("--huber-factor", options.huber_factor,
                 "Huber ICP: delta = factor x median residual")
      ->capture_default_str();
  app.add_option("--gt-mode", gt_mode,
                 "Banmo protocol: dense (both meshes are surfaces: --dense-samples area-uniform "
                 "samples of each, distances to the other's triangles) or vertices (vertices "
                 "only, BANMo's script, for comparison with the paper)")
      ->capture_default_str();
  app.add_option("--samples", options.num_samples, "Surface protocol: samples per mesh")
      ->capture_default_str();
  app.add_option("--dense-samples", options.dense_samples,
                 "Banmo protocol, --gt-mode dense: area-uniform samples of each surface")
      ->capture_default_str();
  app.add_option("--dense-icp-queries", options.dense_icp_queries,
                 "Banmo protocol, --gt-mode dense: predicted samples used as ICP queries (0 = "
                 "all)")
      ->capture_default_str();
  app.add_option("--icp-queries", options.icp_max_queries,
                 "Surface protocol: ICP query points per direction (0 = all samples)")
      ->capture_default_str();
  app.add_option("--seed", options.seed, "Seed of the surface samples")->capture_default_str();
  app.add_option("--max-scale-change", options.max_scale_change,
                 "Surface protocol: ICP scale stays within [s0/k, s0*k]")
      ->capture_default_str();
  app.add_option("--gt-max-edge", options.gt_max_edge,
                 "Banmo protocol, --gt-mode vertices only: subdivide the ground truth (surface "
                 "unchanged) until no edge is longer than this (normalised units, longest bbox "
                 "edge 2; 0 = off, as BANMo's script). The previous dense protocol; slow")
      ->capture_default_str();
  bool one_sided = false;
  app.add_flag("--one-sided-icp", one_sided,
               "Surface protocol: only prediction->GT correspondences in ICP");
  app.add_option("--threads", threads, "Worker threads (0 = all cores)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  options.protocol = ParseEvalProtocol(protocol, "--protocol");
  options.robust = ParseRobustLoss(robust, "--robust");
  options.gt_mode = ParseGtMode(gt_mode, "--gt-mode");
  options.symmetric_icp = !one_sided;
  if (options.gt_max_edge > 0.0 && options.gt_mode == GtMode::kDense) {
    ThrowInputError(
        "--gt-max-edge: applies to --gt-mode vertices only (the previous dense "
        "protocol); the default --gt-mode dense already measures against the exact "
        "ground-truth surface (docs/eval.md)");
  }
  options.Check();
  if (threads < 0) ThrowInputError("--threads: must be >= 0, got ", threads);
  if (threads > 0) SetNumThreads(threads);

  const std::vector<std::string> pred_files = ResolveMeshPaths(pred_path, "--pred");
  const std::vector<std::string> gt_files = ResolveMeshPaths(gt_path, "--gt");
  if (pred_files.size() != gt_files.size()) {
    // A common slip: `banmo solve` writes the per-frame meshes to
    // OUT/meshes/frames/, beside the canonical and rest meshes in OUT/meshes/.
    std::string hint;
    std::error_code ec;
    const std::filesystem::path frames = std::filesystem::path(pred_path) / "frames";
    if (std::filesystem::is_directory(frames, ec)) {
      hint = "; did you mean --pred " + frames.string() + "?";
    }
    ThrowInputError("frame counts differ: --pred ", pred_path, " has ", pred_files.size(),
                    " meshes but --gt ", gt_path, " has ", gt_files.size(),
                    " (expected one prediction per ground-truth frame)", hint);
  }
  std::fprintf(stderr, "banmo eval: %zu frame(s), protocol %s%s\n", gt_files.size(),
               protocol.c_str(),
               options.protocol == EvalProtocol::kBanmo
                   ? (", ground truth " + GtModeName(options.gt_mode)).c_str()
                   : "");
  const Timer timer;
  const std::vector<TriangleMesh> pred = ReadMeshes(pred_files);
  const std::vector<TriangleMesh> gt = ReadMeshes(gt_files);
  const int total = static_cast<int>(gt.size());
  const EvalReport report = EvaluateSequence(
      pred, gt, options, pred_files, gt_files, [&](int frame, int done, const FrameEval& result) {
        std::fprintf(stderr, "  %d/%d done: frame %d, CD %.3f cm (%.1f s)\n", done, total, frame,
                     result.ChamferCm(), timer.Seconds());
      });
  std::fputs(FormatReportTable(report).c_str(), stdout);
  if (!out_dir.empty()) {
    WriteEvalOutputs(out_dir, report, options);
    std::printf("wrote %s/per_frame.csv and %s/summary.json\n", out_dir.c_str(), out_dir.c_str());
  }
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(eval, "Chamfer distance and F-score against ground-truth meshes (ICP)",
                       banmo::RunEval);
