// banmo export: an animatable glTF 2.0 (.glb, or .gltf with embedded buffer)
// of a model checkpoint: canonical mesh with vertex colours, one joint per
// bone, top-4 skinning weights, one animation per video. docs/export.md.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/extract/extract.h"
#include "banmo/gltf/export.h"
#include "banmo/model/model_file.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"
#include "command.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> SplitCommas(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

int RunExport(int argc, char** argv) {
  CLI::App app{
      "Export a model checkpoint as an animatable glTF 2.0 file (docs/export.md): the canonical "
      "mesh (marching cubes of the SDF, vertex colours), a skin with one joint per bone (bind "
      "pose = rest bones) and the top-4 skinning weights per vertex, and one animation per video "
      "(named video00, video01, ...) with the root pose and bone transforms of every frame as "
      "keys at t/fps seconds. Posed at a key, the mesh is the frame's articulated mesh in its "
      "camera coordinates, turned 180 degrees about x (OpenCV y-down to glTF y-up). Open it in "
      "Blender (File > Import > glTF 2.0) or any glTF viewer.",
      "banmo export"};
  std::string model_dir, out_path, interpolation = "linear", names;
  GltfExportOptions options;
  bool no_colors = false;
  int threads = 0;
  app.add_option("--model", model_dir, "Model checkpoint folder (written by banmo solve)")
      ->required();
  app.add_option("--out", out_path,
                 "Output file: .glb (binary) or .gltf (JSON with the buffer embedded); an "
                 "existing file is replaced")
      ->required();
  app.add_option("--resolution", options.extract.grid.resolution,
                 "Marching-cubes cells along the longest axis of the canonical box (the box "
                 "training sampled, stored with the model; [-1, 1]^3 for a model without one)")
      ->capture_default_str();
  app.add_option("--fps", options.fps, "Animation keys per second (frame t at t/fps s)")
      ->capture_default_str();
  app.add_option("--interpolation", interpolation,
                 "Animation interpolation between keys: linear (smooth playback) or step")
      ->capture_default_str();
  app.add_option("--color-video", options.extract.color_video,
                 "Appearance code of this video for the vertex colours (-1 = zero code)")
      ->capture_default_str();
  app.add_option("--video-names", names,
                 "Comma-separated animation names, one per video (default video00, video01, ...)");
  app.add_flag("--no-colors", no_colors, "Do not write vertex colours (COLOR_0)");
  app.add_option("--threads", threads, "Worker threads (0 = all cores)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (threads < 0) ThrowInputError("--threads: expected >= 0, got ", threads);
  if (threads > 0) SetNumThreads(threads);
  if (options.extract.grid.resolution < 2) {
    ThrowInputError("--resolution: expected >= 2, got ", options.extract.grid.resolution);
  }
  if (!(options.fps > 0) || !std::isfinite(options.fps)) {
    ThrowInputError("--fps: expected a number > 0, got ", options.fps);
  }
  if (interpolation == "linear") {
    options.interpolation = GltfInterpolation::kLinear;
  } else if (interpolation == "step") {
    options.interpolation = GltfInterpolation::kStep;
  } else {
    ThrowInputError("--interpolation: expected linear or step, got '", interpolation, "'");
  }
  if (options.extract.color_video < -1) {
    ThrowInputError("--color-video: expected >= -1, got ", options.extract.color_video);
  }
  options.vertex_colors = !no_colors;
  const fs::path out(out_path);
  const std::string ext = out.extension().string();
  if (ext != ".glb" && ext != ".gltf") {
    ThrowInputError("--out '", out_path, "': expected a file name ending in .glb or .gltf");
  }
  std::error_code ec;
  if (fs::is_directory(out, ec)) ThrowInputError("--out '", out_path, "' is a folder");
  const fs::path parent = out.has_parent_path() ? out.parent_path() : fs::path(".");
  if (!fs::is_directory(parent, ec)) {
    ThrowInputError("--out '", out_path, "': folder '", parent.string(), "' does not exist");
  }
  if (::access(parent.c_str(), W_OK) != 0) {
    ThrowInputError("--out '", out_path, "': folder '", parent.string(), "' is not writable");
  }
  if (!fs::is_directory(model_dir, ec)) {
    ThrowInputError("--model '", model_dir,
                    "': not a folder (expected a checkpoint folder "
                    "written by banmo solve, e.g. OUT/checkpoint)");
  }
  if (!fs::exists(fs::path(model_dir) / "model.yaml", ec)) {
    ThrowInputError("--model '", model_dir,
                    "': no model.yaml (expected a checkpoint folder written by banmo solve, "
                    "e.g. OUT/checkpoint)");
  }

  Timer total;
  const std::unique_ptr<Model> model = LoadModel(model_dir);
  if (!names.empty()) {
    options.video_names = SplitCommas(names);
    if (static_cast<int>(options.video_names.size()) != model->num_videos()) {
      ThrowInputError("--video-names: ", options.video_names.size(), " names for ",
                      model->num_videos(), " videos");
    }
  }
  const Eigen::AlignedBox3d box = ExtractionBounds(*model);
  options.extract.grid.bounds_min = box.min();
  options.extract.grid.bounds_max = box.max();
  options.Check();
  int num_frames = 0;
  for (int v = 0; v < model->num_videos(); ++v) {
    num_frames += static_cast<int>(model->video(v).frames.size());
  }
  std::printf("model %s: %d videos, %d frames, %d bones\n", model_dir.c_str(), model->num_videos(),
              num_frames, model->num_bones());
  std::fflush(stdout);
  // The file is written beside under a temporary name and renamed; a killed
  // run's temporary file is removed here.
  if (const int stale = RemoveStaleTempFilesOf(out_path); stale > 0) {
    std::fprintf(stderr, "banmo export: removed %d temporary file(s) of a killed run beside %s\n",
                 stale, out_path.c_str());
  }
  const GltfExportSummary s = ExportGltf(*model, options, out_path, [](const std::string& line) {
    std::fprintf(stderr, "  %s\n", line.c_str());
  });
  std::printf(
      "wrote %s (%.1f KB): %d vertices, %d faces, %d joints, %d animations, %d keyframes at "
      "%g fps (%s)%s; total %.2f s\n",
      out_path.c_str(), s.bytes / 1024.0, s.vertices, s.faces, s.joints, s.animations, s.keyframes,
      options.fps, interpolation.c_str(),
      model->num_bones() > 4 ? (", top-4 weights drop at most " +
                                std::to_string(s.max_dropped_weight) + " weight per vertex")
                                   .c_str()
                             : "",
      total.Seconds());
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(export, "Export a model as an animatable glTF 2.0 (.glb) file",
                       banmo::RunExport);
