#include "banmo/visualize/sequence.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "banmo/extract/extract.h"
#include "banmo/geometry/se3.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

PinholeCamera ScaledCamera(const PinholeCamera& camera, int scale) {
  PinholeCamera c = camera;
  c.width *= scale;
  c.height *= scale;
  c.intrinsics *= scale;
  return c;
}

std::string FormatDouble(double x) {
  if (std::isnan(x)) return "nan";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", x);
  return buf;
}

// Writes the panel images as an MP4 with the first codec OpenCV's FFmpeg
// backend accepts; returns an empty string and sets *note if none does.
std::string WriteVideo(const std::vector<cv::Mat>& images, double fps, const std::string& path,
                       std::string* note) {
  if (images.empty()) {
    *note = "no frames";
    return "";
  }
  // The temporary name keeps the .mp4 extension: OpenCV picks the container
  // from it.
  const std::string temp = path + ".partial.mp4";
  const cv::Size size = images[0].size();
  for (const char* codec : {"avc1", "mp4v"}) {
    cv::VideoWriter writer;
    const int fourcc = cv::VideoWriter::fourcc(codec[0], codec[1], codec[2], codec[3]);
    if (!writer.open(temp, cv::CAP_FFMPEG, fourcc, fps, size, true)) {
      std::remove(temp.c_str());
      continue;
    }
    for (const cv::Mat& rgb : images) {
      cv::Mat bgr;
      cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
      writer.write(bgr);
    }
    writer.release();
    std::error_code ec;
    if (!fs::exists(temp, ec) || fs::file_size(temp, ec) == 0) {
      std::remove(temp.c_str());
      continue;
    }
    fs::rename(temp, path, ec);
    if (ec) {
      std::remove(temp.c_str());
      ThrowInputError(path, ": could not rename the video into place: ", ec.message());
    }
    *note = std::string("codec ") + codec;
    return path;
  }
  *note = "OpenCV's VideoWriter (FFmpeg backend) accepted neither avc1 nor mp4v; no MP4 written";
  return "";
}

}  // namespace

void RenderSequenceOptions::Check() const {
  frame.Check();
  if (mesh_resolution != 0 && mesh_resolution < 8) {
    ThrowInputError("mesh_resolution: expected 0 (off) or >= 8, got ", mesh_resolution);
  }
  if (!(rgb_error_max > 0)) ThrowInputError("rgb_error_max: expected > 0, got ", rgb_error_max);
  if (!(mask_error_max > 0)) ThrowInputError("mask_error_max: expected > 0, got ", mask_error_max);
  if (!(flow_error_max > 0)) ThrowInputError("flow_error_max: expected > 0, got ", flow_error_max);
  if (scale < 1 || scale > 16) ThrowInputError("scale: expected 1..16, got ", scale);
  if (!(fps > 0)) ThrowInputError("fps: expected > 0, got ", fps);
  if (turntable_views < 0 || turntable_views > 3600) {
    ThrowInputError("turntable_views: expected 0..3600, got ", turntable_views);
  }
}

std::string FrameStem(int video, int frame) {
  char name[64];
  std::snprintf(name, sizeof(name), "video%02d_frame%05d", video, frame);
  return name;
}

cv::Mat FramePanels(const ObservedFrame& observed, const RenderedFrame& rendered,
                    const TriangleMesh& mesh_in_camera, const TriangleMesh& bone_mesh_in_camera,
                    const PinholeCamera& camera, const RenderSequenceOptions& options) {
  const int s = options.scale;
  const PinholeCamera scaled = ScaledCamera(camera, s);
  std::vector<cv::Mat> panels;
  panels.push_back(UpscalePanel(ToRgb8(observed.rgb), s));
  panels.push_back(UpscalePanel(ToRgb8(rendered.rgb), s));
  panels.push_back(UpscalePanel(MaskAgreementImage(rendered.opacity, observed.mask), s));
  ShadeOptions grey;
  panels.push_back(ShadeMesh(mesh_in_camera, scaled, grey));
  ShadeOptions bones;
  bones.use_vertex_colors = true;
  panels.push_back(ShadeMesh(bone_mesh_in_camera, scaled, bones));
  if (options.labels) {
    const char* names[5] = {"input", "rendered", "mask", "mesh", "bones"};
    for (int i = 0; i < 5; ++i) DrawLabel(&panels[i], names[i]);
  }
  return ConcatPanels(panels);
}

cv::Mat ErrorPanels(const ErrorMaps& errors, const RenderSequenceOptions& options) {
  const int s = options.scale;
  std::vector<cv::Mat> panels = {
      UpscalePanel(ColorizeError(errors.rgb, options.rgb_error_max), s),
      UpscalePanel(ColorizeError(errors.mask, options.mask_error_max), s),
      UpscalePanel(ColorizeError(errors.flow, options.flow_error_max), s)};
  if (options.labels) {
    DrawLabel(&panels[0], "rgb 0-" + FormatDouble(options.rgb_error_max));
    DrawLabel(&panels[1], "mask 0-" + FormatDouble(options.mask_error_max));
    DrawLabel(&panels[2], "flow 0-" + FormatDouble(options.flow_error_max) + "px");
  }
  return ConcatPanels(panels);
}

SequenceSummary RenderSequence(
    const Model& model, const Dataset& dataset, const std::vector<std::pair<int, int>>& frames,
    const RenderSequenceOptions& options, const std::string& out_dir,
    const std::function<void(const FrameReport&, int done, int total)>& progress) {
  options.Check();
  CheckDatasetMatchesModel(dataset, model, dataset.root.empty() ? "dataset" : dataset.root);
  for (const auto& [v, t] : frames) {
    CHECK(v >= 0 && v < model.num_videos()) << "video " << v;
    CHECK(t >= 0 && t < static_cast<int>(model.video(v).frames.size())) << "frame " << t;
  }
  SequenceSummary summary;

  // Canonical mesh and its dominant-bone colours, once.
  Timer mesh_timer;
  TriangleMesh canonical, bone_canonical;
  if (options.mesh_resolution > 0) {
    ExtractOptions extract;
    extract.grid.resolution = options.mesh_resolution;
    extract.grid.bounds_min = options.frame.canonical_bounds.min();
    extract.grid.bounds_max = options.frame.canonical_bounds.max();
    canonical = ExtractCanonicalMesh(model, extract);
    if (canonical.NumVertices() > 0) {
      bone_canonical =
          model.num_bones() > 0
              ? ColorByDominantBone(canonical, SkinningWeightsAt(model, canonical.vertices))
              : canonical;
    }
  }
  summary.mesh_vertices = canonical.NumVertices();
  summary.mesh_seconds = mesh_timer.Seconds();

  MakeDirectories(out_dir + "/frames");
  MakeDirectories(out_dir + "/errors");
  std::ostringstream csv;
  csv << "video,frame,partner_frame,rgb_error,mask_error,mask_iou,flow_epe,rgb_pixels,"
         "mask_pixels,flow_pixels,volume_seconds,total_seconds,psnr\n";
  std::vector<cv::Mat> video_frames;
  int done = 0;
  for (const auto& [v, t] : frames) {
    Timer frame_timer;
    FrameReport report;
    report.video = v;
    report.frame = t;
    const ObservedFrame observed = ObserveFrame(dataset, v, t, options.frame.flow_gap);
    Timer volume_timer;
    const RenderedFrame rendered = RenderFrame(model, observed, options.frame);
    report.volume_seconds = volume_timer.Seconds();
    report.partner_frame = rendered.partner_frame;
    const ErrorMaps errors = ComputeErrorMaps(rendered, observed);
    report.errors = SummarizeErrors(errors, rendered, observed);

    PinholeCamera camera = model.video(v).camera;
    camera.intrinsics = model.video(v).intrinsics;  // what the rays use
    TriangleMesh posed, bone_posed;
    if (canonical.NumFaces() > 0) {
      posed = ArticulateMesh(model, canonical, v, t);
      bone_posed = posed;
      bone_posed.colors = bone_canonical.colors;
    }
    const cv::Mat panels = FramePanels(observed, rendered, posed, bone_posed, camera, options);
    const std::string stem = FrameStem(v, t);
    WriteFileAtomic(out_dir + "/frames/" + stem + ".png", EncodePng(panels));
    WriteFileAtomic(out_dir + "/errors/" + stem + ".png", EncodePng(ErrorPanels(errors, options)));
    if (options.write_video) video_frames.push_back(panels);
    report.total_seconds = frame_timer.Seconds();

    const FrameErrors& e = report.errors;
    csv << v << "," << t << "," << report.partner_frame << "," << FormatDouble(e.rgb) << ","
        << FormatDouble(e.mask) << "," << FormatDouble(e.mask_iou) << "," << FormatDouble(e.flow)
        << "," << e.rgb_pixels << "," << e.mask_pixels << "," << e.flow_pixels << ","
        << FormatDouble(report.volume_seconds) << "," << FormatDouble(report.total_seconds) << ","
        << FormatDouble(e.psnr) << "\n";
    summary.frames.push_back(report);
    ++done;
    if (progress) progress(report, done, static_cast<int>(frames.size()));
  }
  WriteFileAtomic(out_dir + "/errors.csv", csv.str());

  if (options.write_video) {
    summary.video_path =
        WriteVideo(video_frames, options.fps, out_dir + "/sequence.mp4", &summary.video_note);
  }

  if (options.turntable_views > 0 && canonical.NumFaces() > 0) {
    // Camera of video 0, frame 0; the mesh turned about its own y axis
    // through its centre, which is placed on the optical axis at the depth
    // where its bounding sphere fills ~80 % of the image height.
    PinholeCamera camera = model.video(0).camera;
    camera.intrinsics = model.video(0).intrinsics;
    const PinholeCamera scaled = ScaledCamera(camera, options.scale);
    const Pose g0 = model.RootPose(0, 0);
    const Eigen::Quaterniond q0(g0[0], g0[1], g0[2], g0[3]);
    const Eigen::Vector3d centre =
        0.5 * (canonical.vertices.rowwise().minCoeff() + canonical.vertices.rowwise().maxCoeff());
    const double radius = (canonical.vertices.colwise() - centre).colwise().norm().maxCoeff();
    const double depth = radius * camera.intrinsics[1] / (0.4 * camera.height);
    MakeDirectories(out_dir + "/turntable");
    ShadeOptions shade;
    shade.use_vertex_colors = true;
    std::vector<cv::Mat> turntable_frames;
    for (int i = 0; i < options.turntable_views; ++i) {
      const double angle = 2.0 * M_PI * i / options.turntable_views;
      const Eigen::Matrix3d r =
          q0.toRotationMatrix() * Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).matrix();
      TriangleMesh view = canonical;
      for (int j = 0; j < view.NumVertices(); ++j) {
        view.vertices.col(j) =
            r * (canonical.vertices.col(j) - centre) + Eigen::Vector3d(0.0, 0.0, depth);
      }
      char name[32];
      std::snprintf(name, sizeof(name), "view%03d.png", i);
      const cv::Mat image = ShadeMesh(view, scaled, shade);
      WriteFileAtomic(out_dir + "/turntable/" + name, EncodePng(image));
      if (options.write_video) turntable_frames.push_back(image);
      ++summary.turntable_written;
    }
    if (options.write_video) {
      std::string note;
      summary.turntable_video_path =
          WriteVideo(turntable_frames, options.fps, out_dir + "/turntable.mp4", &note);
    }
  }
  return summary;
}

}  // namespace banmo
