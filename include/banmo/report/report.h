// One HTML page per run (`banmo report`, docs/report.md): what a solve wrote
// (config, stages, losses, evaluation, root-pose errors, held-out frames),
// `banmo render`'s panels and turntable for a few frames, per-frame plots and
// loss curves as inline SVG, and an interactive viewer of the exported
// animated glTF (three.js r111 from Debian's libjs-three, classic scripts,
// the GLB embedded as base64 in model.js so the page opens from file://).
//
// Files written (the folder is built as RUN/report.tmp and renamed into
// place, so an earlier report is replaced only by a complete one):
//   RUN/report/index.html            the page
//   RUN/report/model.glb, model.js   the export (no Draco) and its base64 copy
//   RUN/report/viewer.js, three/     the viewer and the three.js files it needs
//   RUN/report/render/               banmo render's output for the chosen frames
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace banmo {

struct ReportOptions {
  // A run folder: `banmo solve`'s --out (holding checkpoint/), or a folder
  // holding solve/ (and data/), as tools/run_default.sh writes.
  std::string run_dir;
  // The dataset the model was trained on; empty: RUN/data, then the solve
  // folder's ../data. Without one the render step is skipped (said so).
  std::string data_dir;
  // Frames rendered per video (evenly spaced, first and last included; 0:
  // no render step) and the render's jittered passes (docs/render.md).
  int frames_per_video = 2;
  int jitter_passes = 4;
  // Views of the canonical mesh's turntable (0: none).
  int turntable_views = 12;
  // Marching-cubes cells of the exported mesh (banmo export --resolution).
  int export_resolution = 128;
  double fps = 10.0;  // animation keys per second (banmo export --fps)
  // Where Debian's libjs-three puts three.js r111.
  std::string three_dir = "/usr/share/javascript/three";

  // Throws InputError naming the option on a bad value.
  void Check() const;
};

// The folders of a run. Throws InputError naming run_dir (or data_dir) when
// no checkpoint is found (or an explicit dataset folder is missing).
struct RunFolders {
  std::string run;    // as given
  std::string solve;  // holds checkpoint/
  std::string data;   // the dataset, empty if none was found
};
RunFolders FindRunFolders(const std::string& run_dir, const std::string& data_dir);

struct ReportSummary {
  std::string index_path;            // RUN/report/index.html
  std::vector<std::string> skipped;  // "what: why", also listed on the page
  double export_seconds = 0.0;
  double render_seconds = 0.0;  // the render step (RenderSequence)
  double total_seconds = 0.0;
};

// Builds RUN/report. progress (optional) gets one line per step.
ReportSummary WriteReport(const ReportOptions& options,
                          const std::function<void(const std::string&)>& progress = nullptr);

// A CSV file as text cells: header and rows (no quoting: the project's CSVs
// have none). Missing file: empty table, exists = false.
struct CsvTable {
  bool exists = false;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  // Column index of `name`, or -1.
  int Column(const std::string& name) const;
  // Cell as a number (NaN if empty, missing or not a number).
  double Number(size_t row, int column) const;
};
CsvTable ReadCsv(const std::string& path);

// Text for HTML element content and attribute values.
std::string HtmlEscape(const std::string& text);

// Base64 (RFC 4648, with padding) of bytes.
std::string Base64(const std::string& bytes);

// A line plot as an inline <svg> element: one polyline per series (NaN
// values break the line), axes with ticks, a legend; log_y plots log10 of
// positive values (others dropped) over at most 8 decades below the largest
// (smaller values on the bottom edge).
struct PlotSeries {
  std::string name;
  std::vector<double> x, y;
  bool points = false;  // markers instead of a line (few points)
};
struct PlotOptions {
  std::string title, x_label, y_label;
  bool log_y = false;
  int width = 640, height = 280;
};
std::string LinePlotSvg(const std::vector<PlotSeries>& series, const PlotOptions& options);

// The viewer script (viewer.js) and the page's style sheet, compiled in.
const char* ReportViewerScript();
const char* ReportStyleSheet();

}  // namespace banmo
