// banmo report: one HTML page per run (RUN/report/index.html) with the run at
// a glance, an interactive viewer of the animated glTF export, banmo render's
// pictures for a few frames, per-frame plots and loss curves. docs/report.md.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "banmo/report/report.h"
#include "banmo/util/error.h"
#include "banmo/util/parallel.h"
#include "command.h"

namespace banmo {
namespace {

int RunReport(int argc, char** argv) {
  CLI::App app{
      "Write RUN/report/index.html (docs/report.md): the run at a glance (dataset, config, "
      "stages with time and rays/s, final losses, Chamfer / F-score or held-out mask IoU and "
      "PSNR when present), an interactive three.js viewer of the animated glTF export (orbit, "
      "play/pause, animation per video, bones, skinning-weight colours), banmo render's panels "
      "and turntable for a few frames per video, per-frame plots and loss curves per stage. The "
      "folder is self-contained: it opens offline from file://. It says what it skipped and why.",
      "banmo report"};
  ReportOptions options;
  int threads = 0;
  app.add_option("--run", options.run_dir,
                 "Run folder: banmo solve's --out (holding checkpoint/) or a folder holding solve/ "
                 "(and data/), as tools/run_default.sh writes")
      ->required();
  app.add_option("--data", options.data_dir,
                 "Dataset the model was trained on (default: RUN/data, or the solve folder's "
                 "../data; none: no pictures)");
  app.add_option("--frames-per-video", options.frames_per_video,
                 "Frames rendered per video, evenly spaced (0 = no render step)")
      ->capture_default_str();
  app.add_option("--jitter-passes", options.jitter_passes,
                 "Jittered renderings averaged per picture (banmo render --jitter-passes)")
      ->capture_default_str();
  app.add_option("--turntable", options.turntable_views,
                 "Views of the canonical mesh's turntable (0 = none)")
      ->capture_default_str();
  app.add_option("--resolution", options.export_resolution,
                 "Marching-cubes cells of the exported mesh (banmo export --resolution)")
      ->capture_default_str();
  app.add_option("--fps", options.fps, "Animation keys per second (banmo export --fps)")
      ->capture_default_str();
  app.add_option("--three-dir", options.three_dir,
                 "three.js r111 as Debian's libjs-three installs it (three.min.js, "
                 "examples/js/loaders/GLTFLoader.js, examples/js/controls/OrbitControls.js)")
      ->capture_default_str();
  app.add_option("--threads", threads, "Worker threads (0 = all cores)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (threads < 0) ThrowInputError("--threads: expected >= 0, got ", threads);
  if (threads > 0) SetNumThreads(threads);
  options.Check();

  const ReportSummary s = WriteReport(options, [](const std::string& line) {
    std::printf("%s\n", line.c_str());
    std::fflush(stdout);
  });
  for (const std::string& skipped : s.skipped) std::printf("skipped: %s\n", skipped.c_str());
  std::printf("wrote %s in %.1f s (render %.1f s, export %.1f s); open it in a browser\n",
              s.index_path.c_str(), s.total_seconds, s.render_seconds, s.export_seconds);
  return 0;
}

}  // namespace
}  // namespace banmo

BANMO_REGISTER_COMMAND(report, "One HTML page per run: viewer, pictures, plots (offline)",
                       banmo::RunReport);
