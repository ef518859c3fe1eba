#include "banmo/report/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "banmo/extract/extract.h"
#include "banmo/gltf/export.h"
#include "banmo/io/dataset.h"
#include "banmo/model/model_file.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/config.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/enum_names.h"
#include "banmo/util/error.h"
#include "banmo/util/timer.h"
#include "banmo/visualize/sequence.h"

namespace banmo {

namespace fs = std::filesystem;

void ReportOptions::Check() const {
  if (frames_per_video < 0) {
    ThrowInputError("--frames-per-video: expected >= 0, got ", frames_per_video);
  }
  if (jitter_passes < 0) ThrowInputError("--jitter-passes: expected >= 0, got ", jitter_passes);
  if (turntable_views < 0) ThrowInputError("--turntable: expected >= 0, got ", turntable_views);
  if (export_resolution < 2) {
    ThrowInputError("--resolution: expected >= 2, got ", export_resolution);
  }
  if (!(fps > 0) || !std::isfinite(fps)) ThrowInputError("--fps: expected > 0, got ", fps);
}

RunFolders FindRunFolders(const std::string& run_dir, const std::string& data_dir) {
  std::error_code ec;
  if (!fs::is_directory(run_dir, ec)) ThrowInputError("--run '", run_dir, "': not a folder");
  RunFolders f;
  f.run = run_dir;
  const auto has_checkpoint = [&](const fs::path& dir) {
    return fs::exists(dir / "checkpoint" / "model.yaml", ec) ||
           fs::exists(dir / "checkpoint.old" / "model.yaml", ec);
  };
  if (has_checkpoint(run_dir)) {
    f.solve = run_dir;
  } else if (has_checkpoint(fs::path(run_dir) / "solve")) {
    f.solve = (fs::path(run_dir) / "solve").string();
  } else {
    ThrowInputError("--run '", run_dir,
                    "': no checkpoint/model.yaml and no solve/checkpoint/model.yaml (expected "
                    "banmo solve's --out, or a folder holding solve/ as tools/run_default.sh "
                    "writes)");
  }
  if (!data_dir.empty()) {
    if (!fs::exists(fs::path(data_dir) / "manifest.yaml", ec)) {
      ThrowInputError("--data '", data_dir,
                      "': no manifest.yaml (expected a dataset folder, "
                      "docs/dataset.md)");
    }
    f.data = data_dir;
  } else {
    for (const fs::path& d : {fs::path(run_dir) / "data", fs::path(f.solve) / ".." / "data"}) {
      if (fs::exists(d / "manifest.yaml", ec)) {
        f.data = d.lexically_normal().string();
        break;
      }
    }
  }
  return f;
}

namespace {

std::string ReadFileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInputError(path, ": cannot read");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string Num(double x, const char* format = "%.3f") {
  if (!std::isfinite(x)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, x);
  return buf;
}

// A JSON file, or null when absent or unreadable (noted in `skipped`).
nlohmann::json ReadJson(const std::string& path, std::vector<std::string>* skipped) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return nullptr;
  try {
    return nlohmann::json::parse(ReadFileText(path));
  } catch (const std::exception& e) {
    skipped->push_back(path + ": not valid JSON (" + e.what() + ")");
    return nullptr;
  }
}

double JsonNumber(const nlohmann::json& j, const char* key) {
  if (j.is_object() && j.contains(key) && j[key].is_number()) return j[key].get<double>();
  return std::numeric_limits<double>::quiet_NaN();
}

// Video and frame from a path holding "video<V>_frame<T>" (eval's per-frame
// CSV names its meshes so).
bool VideoFrameFromName(const std::string& name, int* video, int* frame) {
  const size_t p = name.rfind("video");
  if (p == std::string::npos) return false;
  return std::sscanf(name.c_str() + p, "video%d_frame%d", video, frame) == 2;
}

// One series per video of column `value` against column `frame` (or the
// video/frame parsed from column `name_column`).
std::vector<PlotSeries> PerVideoSeries(const CsvTable& table, const std::string& value,
                                       const std::string& name_column, bool points) {
  std::map<int, PlotSeries> by_video;
  const int vc = table.Column("video"), fc = table.Column("frame"), yc = table.Column(value);
  const int nc = name_column.empty() ? -1 : table.Column(name_column);
  if (yc < 0) return {};
  for (size_t r = 0; r < table.rows.size(); ++r) {
    int video = 0, frame = static_cast<int>(r);
    if (nc >= 0 && static_cast<size_t>(nc) < table.rows[r].size()) {
      if (!VideoFrameFromName(table.rows[r][nc], &video, &frame)) continue;
    } else {
      if (vc >= 0) video = static_cast<int>(table.Number(r, vc));
      if (fc >= 0) frame = static_cast<int>(table.Number(r, fc));
    }
    PlotSeries& s = by_video[video];
    s.name = "video " + std::to_string(video);
    s.points = points;
    s.x.push_back(frame);
    s.y.push_back(table.Number(r, yc));
  }
  std::vector<PlotSeries> out;
  for (auto& [v, s] : by_video) out.push_back(std::move(s));
  return out;
}

// Frames 0..T-1 of a video, `count` of them evenly spaced (first and last
// included).
std::vector<int> EvenFrames(int frames, int count) {
  std::vector<int> out;
  if (frames <= 0 || count <= 0) return out;
  if (count == 1 || frames == 1) return {0};
  for (int i = 0; i < count && i < frames; ++i) {
    const int t = static_cast<int>(
        std::lround(static_cast<double>(i) * (frames - 1) / (std::min(count, frames) - 1)));
    if (out.empty() || out.back() != t) out.push_back(t);
  }
  return out;
}

// Copies the three.js r111 classic scripts the viewer needs into dir/three;
// returns an empty string or why it could not.
std::string CopyThree(const std::string& three_dir, const std::string& dir) {
  const std::vector<std::pair<std::string, std::string>> files = {
      {"build/three.min.js", "three.min.js"},
      {"examples/js/loaders/GLTFLoader.js", "GLTFLoader.js"},
      {"examples/js/controls/OrbitControls.js", "OrbitControls.js"}};
  std::error_code ec;
  for (const auto& [from, to] : files) {
    if (!fs::exists(fs::path(three_dir) / from, ec)) {
      return "three.js r111 not found (" + (fs::path(three_dir) / from).string() +
             " missing; apt-get install libjs-three, or tools/install_deps.sh)";
    }
  }
  MakeDirectories(dir + "/three");
  for (const auto& [from, to] : files) {
    WriteFileAtomic(dir + "/three/" + to, ReadFileText((fs::path(three_dir) / from).string()));
  }
  return "";
}

struct Page {
  std::ostringstream body;
  std::vector<std::string> skipped;
  void Skip(const std::string& what) { skipped.push_back(what); }
};

void TableRow(std::ostringstream& os, const std::vector<std::string>& cells, bool header = false) {
  os << "<tr>";
  for (const std::string& c : cells) {
    const bool numeric = !c.empty() && (std::isdigit(static_cast<unsigned char>(c[0])) ||
                                        (c[0] == '-' && c.size() > 1));
    os << (header ? "<th>" : (numeric ? "<td class=\"num\">" : "<td>")) << HtmlEscape(c)
       << (header ? "</th>" : "</td>");
  }
  os << "</tr>\n";
}

// The dataset at a glance.
void DatasetSection(const Dataset& dataset, const std::string& data_dir, Page* page) {
  std::ostringstream& os = page->body;
  os << "<h3>Dataset</h3>\n<p class=\"note\">" << HtmlEscape(data_dir) << ": "
     << dataset.videos.size() << " videos, " << dataset.NumFrames() << " frames, flow gaps ";
  for (size_t i = 0; i < dataset.flow_gaps.size(); ++i) {
    os << (i ? "," : "") << dataset.flow_gaps[i];
  }
  os << "</p>\n<table>\n";
  TableRow(os,
           {"video", "name", "frames", "size", "focal (px)", "features", "flow", "GT root poses",
            "GT meshes", "skipped frames"},
           true);
  for (size_t v = 0; v < dataset.videos.size(); ++v) {
    const Video& video = dataset.videos[v];
    int skipped = 0;
    for (const Frame& f : video.frames) skipped += f.skip ? 1 : 0;
    TableRow(os, {std::to_string(v), video.name, std::to_string(video.frames.size()),
                  std::to_string(video.camera.width) + " x " + std::to_string(video.camera.height),
                  Num(video.camera.intrinsics[0], "%.1f"), video.present.features ? "yes" : "no",
                  video.present.flow ? "yes" : "no", video.present.root_poses_gt ? "yes" : "no",
                  video.present.gt_mesh ? "yes" : "no", std::to_string(skipped)});
  }
  os << "</table>\n";
}

// Stages from config.yaml, with times from stages.csv.
void StagesSection(const RunFolders& f, const CsvTable& stages, const CsvTable& losses,
                   Page* page) {
  std::ostringstream& os = page->body;
  os << "<h3>Stages</h3>\n";
  std::vector<StageConfig> config_stages;
  try {
    config_stages = LoadSolverConfig(f.solve + "/config.yaml").stages;
  } catch (const std::exception& e) {
    page->Skip("stage settings: " + f.solve + "/config.yaml: " + e.what());
  }
  if (!stages.exists) {
    page->Skip("stage times and rays/s: no " + f.solve +
               "/stages.csv (written by banmo solve since the report exists; an older solve)");
  }
  // Final losses: the last row of each stage in losses.csv.
  std::map<std::string, size_t> last_row;
  const int name_col = losses.Column("stage_name");
  for (size_t r = 0; r < losses.rows.size(); ++r) {
    if (name_col >= 0 && static_cast<size_t>(name_col) < losses.rows[r].size()) {
      last_row[losses.rows[r][name_col]] = r;
    }
  }
  os << "<table>\n";
  TableRow(os,
           {"stage", "batches", "rays / batch", "samples / ray", "step rule", "time (s)", "rays/s",
            "final losses (last batch)"},
           true);
  const size_t n = std::max(config_stages.size(), stages.rows.size());
  for (size_t i = 0; i < n; ++i) {
    std::string name = i < config_stages.size() ? config_stages[i].name : "";
    std::string seconds = "", rays = "";
    const int sn = stages.Column("name");
    for (size_t r = 0; r < stages.rows.size(); ++r) {
      if (sn >= 0 && static_cast<size_t>(sn) < stages.rows[r].size() &&
          (stages.rows[r][sn] == name || (name.empty() && r == i))) {
        name = stages.rows[r][sn];
        seconds = Num(stages.Number(r, stages.Column("seconds")), "%.1f");
        rays = Num(stages.Number(r, stages.Column("rays_per_second")), "%.0f");
      }
    }
    std::string final_losses;
    if (const auto it = last_row.find(name); it != last_row.end()) {
      for (size_t c = 0; c < losses.header.size(); ++c) {
        const std::string& h = losses.header[c];
        if (h == "stage" || h == "stage_name" || h == "batch" || h == "total_batch" ||
            h == "seconds")
          continue;
        const double value = losses.Number(it->second, static_cast<int>(c));
        if (std::isfinite(value)) final_losses += h + "=" + Num(value, "%.4g") + " ";
      }
    }
    if (i < config_stages.size()) {
      const StageConfig& s = config_stages[i];
      TableRow(os, {name, std::to_string(s.batches), std::to_string(s.batch_rays),
                    std::to_string(s.samples_per_ray), EnumName(s.step_rule), seconds, rays,
                    final_losses});
    } else {
      TableRow(os, {name, "", "", "", "", seconds, rays, final_losses});
    }
  }
  os << "</table>\n";
}

// One loss plot per stage: every term against the stage's batch, log scale,
// thinned to at most ~500 points per curve (means over bins of batches).
void LossSection(const CsvTable& losses, const std::string& solve_dir, Page* page) {
  std::ostringstream& os = page->body;
  os << "<h2 id=\"losses\">Loss curves</h2>\n";
  if (!losses.exists) {
    os << "<p class=\"note\">skipped: no losses.csv</p>\n";
    page->Skip("loss curves: no " + solve_dir +
               "/losses.csv (written by banmo solve since the report exists; an older solve)");
    return;
  }
  os << "<p class=\"note\">Per-term mean losses of each batch (1/2 |r|^2 per ray after "
        "weights, as the progress lines print them), from "
     << HtmlEscape(solve_dir) << "/losses.csv.</p>\n";
  const int name_col = losses.Column("stage_name"), batch_col = losses.Column("batch");
  std::vector<std::string> order;
  std::map<std::string, std::vector<size_t>> rows;
  for (size_t r = 0; r < losses.rows.size(); ++r) {
    if (name_col < 0 || static_cast<size_t>(name_col) >= losses.rows[r].size()) continue;
    const std::string& name = losses.rows[r][name_col];
    if (rows.find(name) == rows.end()) order.push_back(name);
    rows[name].push_back(r);
  }
  for (const std::string& stage : order) {
    const std::vector<size_t>& rs = rows[stage];
    const size_t bin = std::max<size_t>(1, rs.size() / 500);
    std::vector<PlotSeries> series;
    for (size_t c = 0; c < losses.header.size(); ++c) {
      const std::string& h = losses.header[c];
      if (h == "stage" || h == "stage_name" || h == "batch" || h == "total_batch" || h == "seconds")
        continue;
      PlotSeries s;
      s.name = h;
      bool any = false;
      for (size_t i = 0; i < rs.size(); i += bin) {
        double x = 0, y = 0;
        int count = 0;
        for (size_t j = i; j < std::min(rs.size(), i + bin); ++j) {
          const double value = losses.Number(rs[j], static_cast<int>(c));
          if (!std::isfinite(value)) continue;
          x += losses.Number(rs[j], batch_col);
          y += value;
          ++count;
        }
        s.x.push_back(count > 0 ? x / count : std::numeric_limits<double>::quiet_NaN());
        s.y.push_back(count > 0 ? y / count : std::numeric_limits<double>::quiet_NaN());
        any = any || count > 0;
      }
      if (any) series.push_back(std::move(s));
    }
    PlotOptions po;
    po.title =
        "stage " + stage + (bin > 1 ? " (means over " + std::to_string(bin) + " batches)" : "");
    po.x_label = "batch";
    po.y_label = "loss";
    po.log_y = true;
    os << LinePlotSvg(series, po);
  }
}

// The viewer section: the model exported to tmp/model.glb (no Draco: a wasm
// decoder does not load from file://), base64 in tmp/model.js, and its HTML;
// a note instead when three.js or the export is missing.
std::string ViewerSection(const ReportOptions& options, const Model& model, const std::string& tmp,
                          Page* page, ReportSummary* summary,
                          const std::function<void(const std::string&)>& say) {
  std::string viewer_html;
  Timer timer;
  std::string why_not = CopyThree(options.three_dir, tmp);
  if (why_not.empty()) {
    try {
      GltfExportOptions eo;
      eo.extract.grid.resolution = options.export_resolution;
      const Eigen::AlignedBox3d box = ExtractionBounds(model);
      eo.extract.grid.bounds_min = box.min();
      eo.extract.grid.bounds_max = box.max();
      eo.fps = options.fps;
      const GltfExportSummary s = ExportGltf(model, eo, tmp + "/model.glb");
      std::ostringstream js;
      js << "// banmo report: the exported model (model.glb) as base64, so the page opens "
            "from file://\n";
      js << "var BANMO_MODEL_INFO = {fps: " << options.fps << ", bones: " << s.joints
         << ", vertices: " << s.vertices << "};\n";
      js << "var BANMO_BONE_PALETTE = [";
      for (int b = 0; b < std::max(1, model.num_bones()); ++b) {
        const auto c = BonePaletteColor(b);
        js << (b ? "," : "") << "[" << int{c[0]} << "," << int{c[1]} << "," << int{c[2]} << "]";
      }
      js << "];\nvar BANMO_MODEL_GLB = \"" << Base64(ReadFileText(tmp + "/model.glb")) << "\";\n";
      WriteFileAtomic(tmp + "/model.js", js.str());
      WriteFileAtomic(tmp + "/viewer.js", ReportViewerScript());
      summary->export_seconds = timer.Seconds();
      char line[256];
      std::snprintf(line, sizeof(line),
                    "export: model.glb %.0f KB, %d vertices, %d joints, %d animations (%.1f s)",
                    s.bytes / 1024.0, s.vertices, s.joints, s.animations, summary->export_seconds);
      say(line);
      std::ostringstream v;
      v << "<h2 id=\"model\">The model</h2>\n<p class=\"note\">The exported animated glTF (<a "
           "href=\"model.glb\">model.glb</a>: "
        << s.vertices << " vertices, " << s.joints << " joints, one animation per video at "
        << options.fps
        << " keys/s; docs/export.md). Drag to orbit, wheel to zoom; the camera starts at "
           "video 0's camera and follows the object.</p>\n"
        << "<div id=\"viewer-controls\"><button id=\"viewer-play\">play</button>"
           "<label>animation <select id=\"viewer-anim\"></select></label>"
           "<input id=\"viewer-time\" type=\"range\" min=\"0\" max=\"1\" step=\"0.01\" "
           "value=\"0\"><span id=\"viewer-time-label\"></span>"
           "<label><input id=\"viewer-bones\" type=\"checkbox\"> bones</label>"
           "<label><input id=\"viewer-weights\" type=\"checkbox\"> skinning weights "
           "(dominant bone)</label></div>\n"
        << "<div id=\"viewer\"></div><p id=\"viewer-status\">loading the viewer ...</p>\n";
      viewer_html = v.str();
    } catch (const InputError& e) {
      why_not = std::string("export failed: ") + e.what();
    }
  }
  if (!why_not.empty()) {
    page->Skip("3D viewer: " + why_not);
    say("viewer skipped: " + why_not);
    viewer_html = "<h2 id=\"model\">The model</h2>\n<p class=\"note\">viewer skipped: " +
                  HtmlEscape(why_not) + "</p>\n";
  }
  return viewer_html;
}

// Pictures: banmo render's panels and turntable for a few frames per video,
// into tmp/render. False (and a note) when there is no dataset or no frame.
bool RenderPictures(const ReportOptions& options, const Model& model, const Dataset& dataset,
                    const std::string& data_dir, const std::string& tmp, Page* page,
                    ReportSummary* summary, RenderSequenceOptions* ro, SequenceSummary* rendered,
                    const std::function<void(const std::string&)>& say) {
  if (data_dir.empty()) {
    page->Skip(
        "pictures and mask IoU: no dataset found (RUN/data or the solve folder's ../data; "
        "give --data)");
    return false;
  }
  if (options.frames_per_video == 0) {
    page->Skip("pictures and mask IoU: --frames-per-video 0");
    return false;
  }
  std::vector<std::pair<int, int>> frames;
  for (int v = 0; v < model.num_videos(); ++v) {
    for (const int t :
         EvenFrames(static_cast<int>(model.video(v).frames.size()), options.frames_per_video)) {
      frames.emplace_back(v, t);
    }
  }
  SetTrainedSampling(model, &ro->frame);
  ro->frame.jitter_passes = options.jitter_passes;
  int height = 1;
  for (int v = 0; v < model.num_videos(); ++v) {
    height = std::max(height, model.video(v).camera.height);
  }
  ro->scale = std::max(1, (256 + height - 1) / height);
  ro->turntable_views = options.turntable_views;
  ro->Check();
  ro->frame.canonical_bounds = CanonicalBoundsFromSurface(model);
  say("render: " + std::to_string(frames.size()) + " frames (" +
      std::to_string(options.frames_per_video) + " per video), " +
      std::to_string(ro->frame.samples_per_ray) + " samples per ray, " +
      std::to_string(ro->frame.jitter_passes) + " jittered passes, turntable " +
      std::to_string(ro->turntable_views) + " views");
  Timer timer;
  *rendered = RenderSequence(
      model, dataset, frames, *ro, tmp + "/render", [&](const FrameReport& r, int done, int all) {
        char line[200];
        std::snprintf(line, sizeof(line),
                      "  [%d/%d] video %d frame %d: IoU %s, rgb error %s (%.1f s)", done, all,
                      r.video, r.frame, Num(r.errors.mask_iou).c_str(), Num(r.errors.rgb).c_str(),
                      r.total_seconds);
        say(line);
      });
  summary->render_seconds = timer.Seconds();
  say("render: done in " + Num(summary->render_seconds, "%.1f") + " s");
  return true;
}

// "The run at a glance": the model, the dataset, the stages, the
// evaluation, the root-pose errors and the held-out frames.
void GlanceSection(const RunFolders& f, const Model& model, const CheckpointInfo& info,
                   const Dataset& dataset, const CsvTable& stages, const CsvTable& losses,
                   const nlohmann::json& eval, const CsvTable& root_errors,
                   const nlohmann::json& holdout, const std::string& holdout_dir, Page* page) {
  std::ostringstream& os = page->body;
  os << "<h2 id=\"glance\">The run at a glance</h2>\n";
  os << "<p>Model: " << model.num_videos() << " videos, " << model.num_bones() << " bones, "
     << EnumName(model.options().density) << " density (beta "
     << Num(std::exp(*model.log_beta()), "%.4g") << "), scene scale "
     << Num(model.scene_scale(), "%.4g") << "; checkpoint (" << HtmlEscape(f.solve)
     << "/checkpoint) at stage index " << info.stage << ", batch " << info.batch
     << " (stage index = number of stages: the solve finished).</p>\n";
  if (!f.data.empty()) DatasetSection(dataset, f.data, page);
  StagesSection(f, stages, losses, page);

  os << "<h3>Against ground truth</h3>\n";
  if (eval.is_object()) {
    os << "<table>\n";
    TableRow(os, {"protocol", "frames", "Chamfer (cm)", "F@1%", "F@2%", "F@5%"}, true);
    TableRow(
        os, {eval.value("protocol", std::string("?")), Num(JsonNumber(eval, "frames"), "%.0f"),
             Num(JsonNumber(eval, "chamfer_cm"), "%.2f"), Num(JsonNumber(eval, "fscore_1"), "%.1f"),
             Num(JsonNumber(eval, "fscore_2"), "%.1f"), Num(JsonNumber(eval, "fscore_5"), "%.1f")});
    os << "</table>\n<p class=\"note\">" << HtmlEscape(f.solve) << "/eval (docs/eval.md).</p>\n";
  } else {
    os << "<p class=\"note\">no evaluation</p>\n";
    page->Skip("Chamfer / F-score: no " + f.solve +
               "/eval/summary.json (no ground-truth meshes in the dataset, or solve --no-eval)");
  }
  if (root_errors.exists) {
    double sum = 0, worst = 0;
    int count = 0;
    const int c = root_errors.Column("rotation_error_deg");
    for (size_t r = 0; r < root_errors.rows.size(); ++r) {
      const double e = root_errors.Number(r, c);
      if (!std::isfinite(e)) continue;
      sum += e;
      worst = std::max(worst, e);
      ++count;
    }
    os << "<p>Root poses: rotation error " << Num(count ? sum / count : NAN, "%.2f")
       << " deg mean, " << Num(worst, "%.2f") << " deg max over " << count
       << " frames (after a global alignment; root_pose_errors.csv).</p>\n";
  } else {
    page->Skip("root-pose error: no " + f.solve +
               "/root_pose_errors.csv (no ground-truth root poses in the dataset)");
  }
  os << "<h3>Held-out frames</h3>\n";
  if (holdout.is_object()) {
    os << "<table>\n";
    std::vector<std::string> keys, values;
    for (auto it = holdout.begin(); it != holdout.end(); ++it) {
      if (!it.value().is_number()) continue;
      keys.push_back(it.key());
      values.push_back(Num(it.value().get<double>(), "%.4g"));
    }
    TableRow(os, keys, true);
    TableRow(os, values);
    os << "</table>\n<p class=\"note\">" << HtmlEscape(holdout_dir)
       << "/summary.json: frames the solve did not fit (banmo solve --holdout-every).</p>\n";
  } else {
    os << "<p class=\"note\">none</p>\n";
    page->Skip(
        "held-out mask IoU and PSNR: no holdout/summary.json (solve without "
        "--holdout-every)");
  }
}

// "Pictures": the rendered panels, error maps and turntable.
void PicturesSection(bool have_render, const RenderSequenceOptions& ro,
                     const SequenceSummary& rendered, Page* page) {
  std::ostringstream& os = page->body;
  os << "<h2 id=\"pictures\">Pictures</h2>\n";
  if (have_render) {
    os << "<p class=\"note\">banmo render's panels (docs/render.md), left to right: input, "
          "rendered RGB (volume rendering, mean of "
       << ro.frame.jitter_passes
       << " jittered passes), mask agreement (white both, red rendered only, blue input only), "
          "the articulated mesh, the mesh by dominant bone; under each (folded) its rgb, mask "
          "and flow error maps.</p>\n";
    for (const FrameReport& r : rendered.frames) {
      const std::string stem = FrameStem(r.video, r.frame);
      os << "<p>video " << r.video << " frame " << r.frame << ": mask IoU "
         << Num(r.errors.mask_iou) << ", rgb error " << Num(r.errors.rgb) << ", flow error "
         << Num(r.errors.flow, "%.2f") << " px</p>\n"
         << "<img class=\"panel\" alt=\"video " << r.video << " frame " << r.frame
         << "\" src=\"render/frames/" << stem << ".png\">\n"
         << "<details><summary>error maps</summary><img class=\"panel\" alt=\"errors\" "
            "src=\"render/errors/"
         << stem << ".png\"></details>\n";
    }
    if (rendered.turntable_written > 0) {
      os << "<h3>Turntable of the canonical shape</h3>\n<div class=\"turntable\">";
      for (int i = 0; i < rendered.turntable_written; ++i) {
        char name[64];
        std::snprintf(name, sizeof(name), "render/turntable/view%03d.png", i);
        os << "<img alt=\"view " << i << "\" src=\"" << name << "\">";
      }
      os << "</div>\n";
    }
  } else {
    os << "<p class=\"note\">skipped (see below)</p>\n";
  }
}

// "Per-frame plots" and the loss curves.
void PlotsSection(const RunFolders& f, const std::string& tmp, bool have_render,
                  const CsvTable& eval_frames, const CsvTable& root_errors,
                  const CsvTable& holdout_frames, const CsvTable& losses, Page* page) {
  std::ostringstream& os = page->body;
  os << "<h2 id=\"plots\">Per-frame plots</h2>\n";
  if (eval_frames.exists) {
    PlotOptions po;
    po.title = "Chamfer distance per frame (eval)";
    po.x_label = "frame";
    po.y_label = "cm";
    os << LinePlotSvg(PerVideoSeries(eval_frames, "chamfer_cm", "pred", false), po);
  }
  if (have_render) {
    const CsvTable errors = ReadCsv(tmp + "/render/errors.csv");
    PlotOptions po;
    po.title = "mask IoU of the rendered frames (render)";
    po.x_label = "frame";
    po.y_label = "IoU";
    os << LinePlotSvg(PerVideoSeries(errors, "mask_iou", "", true), po);
  }
  if (root_errors.exists) {
    PlotOptions po;
    po.title = "root-pose rotation error per frame";
    po.x_label = "frame";
    po.y_label = "degrees";
    os << LinePlotSvg(PerVideoSeries(root_errors, "rotation_error_deg", "", false), po);
  }
  if (holdout_frames.exists) {
    for (const char* column : {"mask_iou", "psnr"}) {
      if (holdout_frames.Column(column) < 0) continue;
      PlotOptions po;
      po.title = std::string("held-out frames: ") + column;
      po.x_label = "frame";
      po.y_label = column;
      os << LinePlotSvg(PerVideoSeries(holdout_frames, column, "", true), po);
    }
  }
  LossSection(losses, f.solve, page);
}

ReportSummary BuildReport(const ReportOptions& options,
                          const std::function<void(const std::string&)>& progress) {
  Timer total;
  const auto say = [&](const std::string& line) {
    if (progress) progress(line);
  };
  const RunFolders f = FindRunFolders(options.run_dir, options.data_dir);
  const std::string out = (fs::path(f.run) / "report").string();
  const std::string tmp = out + ".tmp";
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec)) {
    ThrowInputError(out, ": exists and is not a folder");
  }
  CheckpointInfo info;
  const std::unique_ptr<Model> model = LoadCheckpoint(f.solve + "/checkpoint", &info);
  Dataset dataset;
  if (!f.data.empty()) {
    LoadOptions load;
    load.load_features = false;
    dataset = LoadDataset(f.data, load);
    CheckDatasetMatchesModel(dataset, *model, f.data);
  }
  say("report: solve folder " + f.solve + ", dataset " + (f.data.empty() ? "none" : f.data) +
      "; writing " + out);
  fs::remove_all(tmp, ec);
  MakeDirectories(tmp);

  ReportSummary summary;
  Page page;
  std::ostringstream& os = page.body;

  const std::string viewer_html = ViewerSection(options, *model, tmp, &page, &summary, say);

  SequenceSummary rendered;
  RenderSequenceOptions ro;
  const bool have_render =
      RenderPictures(options, *model, dataset, f.data, tmp, &page, &summary, &ro, &rendered, say);

  // Files the solve (and eval) wrote.
  const CsvTable losses = ReadCsv(f.solve + "/losses.csv");
  const CsvTable stages = ReadCsv(f.solve + "/stages.csv");
  const nlohmann::json eval = ReadJson(f.solve + "/eval/summary.json", &page.skipped);
  const CsvTable eval_frames = ReadCsv(f.solve + "/eval/per_frame.csv");
  const CsvTable root_errors = ReadCsv(f.solve + "/root_pose_errors.csv");
  std::string holdout_dir = f.solve + "/holdout";
  if (!fs::exists(holdout_dir + "/summary.json", ec)) holdout_dir = f.run + "/holdout";
  const nlohmann::json holdout = ReadJson(holdout_dir + "/summary.json", &page.skipped);
  const CsvTable holdout_frames = ReadCsv(holdout_dir + "/frames.csv");

  // The page.
  os << "<h1>banmo report: " << HtmlEscape(f.run) << "</h1>\n";
  os << "<p class=\"note\"><a href=\"#model\">model</a> | <a href=\"#glance\">at a glance</a> | "
        "<a href=\"#pictures\">pictures</a> | <a href=\"#plots\">per-frame plots</a> | <a "
        "href=\"#losses\">loss curves</a> | <a href=\"#skipped\">skipped</a></p>\n";
  os << viewer_html;
  GlanceSection(f, *model, info, dataset, stages, losses, eval, root_errors, holdout, holdout_dir,
                &page);

  PicturesSection(have_render, ro, rendered, &page);
  PlotsSection(f, tmp, have_render, eval_frames, root_errors, holdout_frames, losses, &page);

  os << "<h2 id=\"skipped\">Skipped</h2>\n";
  if (page.skipped.empty()) {
    os << "<p class=\"note\">nothing</p>\n";
  } else {
    os << "<ul class=\"skipped\">\n";
    for (const std::string& s : page.skipped) os << "<li>" << HtmlEscape(s) << "</li>\n";
    os << "</ul>\n";
  }
  std::error_code config_ec;
  if (fs::exists(f.solve + "/config.yaml", config_ec)) {
    os << "<h2 id=\"config\">Config</h2>\n<details><summary>" << HtmlEscape(f.solve)
       << "/config.yaml</summary>\n<pre>" << HtmlEscape(ReadFileText(f.solve + "/config.yaml"))
       << "</pre></details>\n";
  }
  os << "<p class=\"note\">Written by banmo report in " << Num(total.Seconds(), "%.1f")
     << " s (render " << Num(summary.render_seconds, "%.1f") << " s, export "
     << Num(summary.export_seconds, "%.1f") << " s).</p>\n";

  std::ostringstream html;
  html << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
       << "<title>banmo report</title>\n<link rel=\"stylesheet\" href=\"style.css\">\n"
       << "</head>\n<body>\n"
       << os.str();
  if (!viewer_html.empty() &&
      page.skipped.end() ==
          std::find_if(page.skipped.begin(), page.skipped.end(),
                       [](const std::string& s) { return s.rfind("3D viewer", 0) == 0; })) {
    html << "<script src=\"three/three.min.js\"></script>\n"
         << "<script src=\"three/GLTFLoader.js\"></script>\n"
         << "<script src=\"three/OrbitControls.js\"></script>\n"
         << "<script src=\"model.js\"></script>\n<script src=\"viewer.js\"></script>\n";
  }
  html << "</body>\n</html>\n";
  WriteFileAtomic(tmp + "/style.css", ReportStyleSheet());
  WriteFileAtomic(tmp + "/index.html", html.str());

  // Replace an earlier report by the complete new one.
  const std::string old = out + ".old";
  fs::remove_all(old, ec);
  if (fs::exists(out, ec)) {
    fs::rename(out, old, ec);
    if (ec) ThrowInputError(out, ": cannot move the earlier report aside: ", ec.message());
  }
  fs::rename(tmp, out, ec);
  if (ec) ThrowInputError(out, ": cannot move the report into place: ", ec.message());
  fs::remove_all(old, ec);

  summary.skipped = page.skipped;
  summary.index_path = out + "/index.html";
  summary.total_seconds = total.Seconds();
  return summary;
}

}  // namespace

ReportSummary WriteReport(const ReportOptions& options,
                          const std::function<void(const std::string&)>& progress) {
  options.Check();
  const RunFolders f = FindRunFolders(options.run_dir, options.data_dir);
  try {
    return BuildReport(options, progress);
  } catch (...) {
    // Nothing half-written: the unfinished folder goes, an earlier report stays.
    std::error_code ec;
    fs::remove_all(fs::path(f.run) / "report.tmp", ec);
    throw;
  }
}

}  // namespace banmo
