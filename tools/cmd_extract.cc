// banmo extract: meshes from a model checkpoint (canonical mesh with colours,
// articulated per-frame meshes in camera coordinates, bones and skinning
// weights). docs/extract.md.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/extract/extract.h"
#include "banmo/model/model_file.h"
#include "banmo/util/error.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"
#include "cli_options.h"
#include "command.h"

namespace banmo {
namespace {

int RunExtract(int argc, char** argv) {
  CLI::App app{
      "Extract meshes from a model checkpoint (docs/extract.md): marching cubes of the SDF zero "
      "level set (every component with at least --min-component-fraction of the largest one's "
      "faces) with vertex colours, articulated per-frame meshes in each "
      "frame's camera coordinates (OUT/frames, ready for `banmo eval --pred OUT/frames`), bone "
      "ellipsoids, the mesh coloured by dominant bone and per-vertex skinning weights.",
      "banmo extract"};
  std::string model_dir, out_dir, frames = "all", bounds = "model";
  ExtractOptions options;
  bool all_components = false;
  int threads = 0;
  app.add_option("--model", model_dir, "Model checkpoint folder (written by banmo solve)")
      ->required();
  app.add_option("--out", out_dir,
                 "Output folder (created; existing files of the same names are "
                 "replaced)")
      ->required();
  app.add_option("--resolution", options.grid.resolution,
                 "Marching-cubes cells along the longest axis of the bounds")
      ->capture_default_str();
  app.add_option("--frames", frames,
                 "Articulated meshes to write: all, none, or a comma-separated list of V:T, "
                 "V:T0-T1, V:* (video V, frame T)")
      ->capture_default_str();
  app.add_option("--bounds", bounds,
                 "Canonical box sampled, in model units (dataset units / scene scale): "
                 "'model' (the box training sampled, stored with the model; [-1, 1]^3 for a "
                 "model without one) or xmin,ymin,zmin,xmax,ymax,zmax")
      ->capture_default_str();
  app.add_option("--level", options.grid.iso_level,
                 "SDF level extracted, in model units (0 = the zero level set the solver "
                 "trains; a negative level is inside it)")
      ->capture_default_str();
  app.add_option("--coarse-stride", options.grid.coarse_stride,
                 "Coarse-to-fine sampling stride (1 = dense; exact for SDF-like fields)")
      ->capture_default_str();
  app.add_option("--color-video", options.color_video,
                 "Appearance code of this video for the vertex colours (-1 = zero code)")
      ->capture_default_str();
  app.add_option("--min-component-fraction", options.min_component_fraction,
                 "Keep the connected components with at least this fraction of the largest "
                 "one's faces (1 = the largest only)")
      ->capture_default_str();
  app.add_flag("--all-components", all_components,
               "Keep every connected component (--min-component-fraction 0)");
  app.add_option("--threads", threads, "Worker threads (0 = all cores)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (threads < 0) ThrowInputError("--threads: expected >= 0, got ", threads);
  if (threads > 0) SetNumThreads(threads);
  std::optional<Eigen::AlignedBox3d> box;
  if (bounds != "model") {
    box = tools::ParseBoxOption("--bounds", bounds,
                                "'model' or 6 numbers xmin,ymin,zmin,xmax,ymax,zmax");
  }
  if (all_components) options.min_component_fraction = 0.0;

  Timer total;
  const std::unique_ptr<Model> model = LoadModel(model_dir);
  if (!box) box = ExtractionBounds(*model);
  options.grid.bounds_min = box->min();
  options.grid.bounds_max = box->max();
  options.Check();
  options.frames = ParseFrameSelection(frames, *model, "--frames");
  int num_frames = 0;
  for (int v = 0; v < model->num_videos(); ++v) {
    num_frames += static_cast<int>(model->video(v).frames.size());
  }
  std::printf("model %s: %d videos, %d frames, %d bones\n", model_dir.c_str(), model->num_videos(),
              num_frames, model->num_bones());
  const GridShape shape = ComputeGridShape(options.grid);
  std::printf("marching cubes on %dx%dx%d cells...\n", shape.cells.x(), shape.cells.y(),
              shape.cells.z());
  std::fflush(stdout);
  Timer frame_timer;
  const ExtractionSummary s = WriteExtraction(*model, options, out_dir, [&](int done, int all) {
    if (done == 0) {
      std::fprintf(stderr, "  canonical mesh done (%.1f s)\n", frame_timer.Seconds());
    } else if (done == all || done % 25 == 0) {
      std::fprintf(stderr, "  posed frames %d/%d (%.1f s)\n", done, all, frame_timer.Seconds());
    }
  });
  std::printf(
      "wrote %s: canonical mesh %d vertices, %d faces (%.2f s); %d articulated frames in "
      "%s/frames (%.2f s); embedding.npy%s; total %.2f s\n",
      out_dir.c_str(), s.canonical_vertices, s.canonical_faces, s.canonical_seconds,
      s.frames_written, out_dir.c_str(), s.articulate_seconds,
      model->num_bones() > 0 ? "; bones.ply, skinning.ply, skinning_weights.npy" : "",
      total.Seconds());
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(extract, "Extract canonical and per-frame meshes from a model checkpoint",
                       banmo::RunExtract);
