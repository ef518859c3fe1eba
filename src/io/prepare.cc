#include "banmo/io/prepare.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>
#include <set>
#include <utility>

#include "banmo/io/codecs.h"
#include "banmo/io/npy.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/median.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace fs = std::filesystem;
namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Files of `dir` whose extension is in `exts`, sorted by name.
std::vector<fs::path> ListFiles(const std::string& dir, const std::set<std::string>& exts,
                                const std::string& what) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) ThrowInputError(dir, ": not a folder (", what, ")");
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.is_regular_file() && exts.count(Lower(e.path().extension().string()))) {
      out.push_back(e.path());
    }
  }
  std::sort(out.begin(), out.end());
  if (out.empty()) ThrowInputError(dir, ": no ", what, " found");
  return out;
}

// Pairs per-frame files with frames: by stem when frame stems are known,
// otherwise in sorted order.
std::vector<fs::path> MatchToFrames(const std::vector<fs::path>& files,
                                    const std::vector<std::string>& frame_stems, int num_frames,
                                    const std::string& dir, const std::string& what) {
  std::vector<fs::path> out;
  if (!frame_stems.empty()) {
    std::map<std::string, fs::path> by_stem;
    for (const fs::path& p : files) {
      if (!by_stem.emplace(p.stem().string(), p).second) {
        ThrowInputError(p.string(), ": two ", what, " files with the stem '", p.stem().string(),
                        "'");
      }
    }
    for (int t = 0; t < num_frames; ++t) {
      const auto it = by_stem.find(frame_stems[t]);
      if (it == by_stem.end()) {
        ThrowInputError(dir, ": no ", what, " for frame '", frame_stems[t],
                        "' (expected a file with the same name stem)");
      }
      out.push_back(it->second);
    }
    return out;
  }
  if (static_cast<int>(files.size()) < num_frames) {
    ThrowInputError(dir, ": ", files.size(), " ", what, " files for ", num_frames,
                    " video frames (expected one per frame, in sorted order)");
  }
  out.assign(files.begin(), files.begin() + num_frames);
  return out;
}

}  // namespace

void PrepareOptions::Check() const {
  if (video_path.empty() == frames_dir.empty()) {
    ThrowInputError("prepare: give exactly one of a video file or a frames folder");
  }
  if (masks_dir.empty()) ThrowInputError("prepare: a masks folder is required");
  if (gaps.empty()) ThrowInputError("prepare: gaps must not be empty");
  std::set<int> seen;
  for (int g : gaps) {
    if (g <= 0 || g >= 100000 || !seen.insert(g).second) {
      ThrowInputError("prepare: gaps must be unique positive integers, found ", g);
    }
  }
  if (intrinsics && !(intrinsics->allFinite() && (*intrinsics)[0] > 0 && (*intrinsics)[1] > 0)) {
    ThrowInputError("prepare: intrinsics must be finite with fx, fy > 0");
  }
  if (!(std::isfinite(default_distance) && default_distance > 0)) {
    ThrowInputError("prepare: default_distance must be > 0, found ", default_distance);
  }
  if (max_frames < 0) ThrowInputError("prepare: max_frames must be >= 0");
  if (max_size != 0 && (max_size < 16 || max_size > 16384)) {
    ThrowInputError("prepare: --max-size must be 0 (as read) or 16..16384 pixels, found ",
                    max_size);
  }
  flow.Check();
  camera_rotation.Check();
}

cv::Mat ConvertMask(const cv::Mat& raw, MaskFormat format, bool binary_01,
                    const std::string& name) {
  CHECK_EQ(raw.type(), CV_8UC1);
  cv::Mat out(raw.size(), CV_8UC1);
  for (int r = 0; r < raw.rows; ++r) {
    const unsigned char* in = raw.ptr<unsigned char>(r);
    unsigned char* o = out.ptr<unsigned char>(r);
    for (int c = 0; c < raw.cols; ++c) {
      const unsigned char v = in[c];
      if (format == MaskFormat::kBanmo) {
        if (v == 0) {
          o[c] = kMaskBackground;
        } else if (v == 128) {
          o[c] = kMaskObject;
        } else if (v == 255) {
          o[c] = kMaskIgnore;
        } else {
          ThrowInputError(name, ": mask value ", int(v), " at (x=", c, ", y=", r,
                          ") is not 0, 128 or 255 (BANMo mask format)");
        }
      } else if (binary_01) {
        if (v > 1) {
          ThrowInputError(name, ": mask value ", int(v), " at (x=", c, ", y=", r,
                          ") in a 0/1 mask set");
        }
        o[c] = v ? kMaskObject : kMaskBackground;
      } else {
        o[c] = v >= 128 ? kMaskObject : kMaskBackground;
      }
    }
  }
  return out;
}

namespace {

// The frames of the video (RGB) and, for a frames folder, their files.
struct RawFrames {
  std::string source;              // the frames folder or video file
  std::vector<cv::Mat> rgb;        // CV_8UC3, RGB
  std::vector<std::string> stems;  // file-name stems (frames folder only)
  std::vector<std::string> files;  // file paths (frames folder only)
  int width = 0;
  int height = 0;
};

RawFrames ReadFrameImages(const PrepareOptions& options) {
  RawFrames out;
  out.source = options.frames_dir;
  const auto files =
      ListFiles(options.frames_dir, {".png", ".jpg", ".jpeg", ".bmp"}, "frame images");
  const int n = options.max_frames > 0
                    ? std::min<int>(options.max_frames, static_cast<int>(files.size()))
                    : static_cast<int>(files.size());
  out.rgb.resize(n);
  for (int t = 0; t < n; ++t) {
    out.stems.push_back(files[t].stem().string());
    out.files.push_back(files[t].string());
  }
  std::vector<std::exception_ptr> errors(n);
  ParallelFor(n, [&](int begin, int end) {
    for (int t = begin; t < end; ++t) {
      try {
        const cv::Mat bgr = cv::imread(files[t].string(), cv::IMREAD_COLOR);
        if (bgr.empty()) ThrowInputError(files[t].string(), ": unreadable image");
        cv::cvtColor(bgr, out.rgb[t], cv::COLOR_BGR2RGB);
      } catch (...) {
        errors[t] = std::current_exception();
      }
    }
  });
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  return out;
}

// Opens a video file with the backends that read files (FFmpeg, GStreamer,
// OpenCV's MJPEG reader), in OpenCV's order. The camera backends that also
// take a name (V4L2 device paths, gPhoto2 cameras) and the image-sequence
// reader (--frames is that) are not tried: probing gPhoto2 scans the USB bus,
// takes about 0.3 s and leaks in libusb, which fails the sanitizer build.
bool OpenVideoFile(const std::string& path, cv::VideoCapture* cap) {
  for (const cv::VideoCaptureAPIs api : cv::videoio_registry::getStreamBackends()) {
    if (api == cv::CAP_GPHOTO2 || api == cv::CAP_V4L2 || api == cv::CAP_IMAGES) continue;
    try {
      if (cap->open(path, api)) return true;
    } catch (const cv::Exception&) {
      // A backend that throws on this file is one that cannot read it.
    }
  }
  return false;
}

RawFrames ReadVideoFile(const PrepareOptions& options) {
  RawFrames out;
  out.source = options.video_path;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(options.video_path, ec)) {
    ThrowInputError(options.video_path, ": cannot open the video file (no such file)");
  }
  cv::VideoCapture cap;
  if (!OpenVideoFile(options.video_path, &cap)) {
    ThrowInputError(options.video_path,
                    ": cannot open the video file (OpenCV VideoCapture: unknown container or "
                    "codec; try extracting the frames with ffmpeg and use --frames)");
  }
  cv::Mat bgr;
  while (cap.read(bgr)) {
    if (bgr.empty()) break;
    if (bgr.type() != CV_8UC3) ThrowInputError(options.video_path, ": expected 8-bit colour");
    cv::Mat rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    out.rgb.push_back(rgb);
    if (options.max_frames > 0 && static_cast<int>(out.rgb.size()) >= options.max_frames) break;
  }
  if (out.rgb.empty()) ThrowInputError(options.video_path, ": no frames could be decoded");
  return out;
}

// Frames from the folder or the video file, all of the same size.
RawFrames ReadFrames(const PrepareOptions& options) {
  RawFrames f = options.frames_dir.empty() ? ReadVideoFile(options) : ReadFrameImages(options);
  f.width = f.rgb[0].cols;
  f.height = f.rgb[0].rows;
  for (std::size_t t = 0; t < f.rgb.size(); ++t) {
    if (f.rgb[t].cols != f.width || f.rgb[t].rows != f.height) {
      const std::string first = f.files.empty() ? "frame 0" : f.files[0];
      const std::string offending =
          f.files.empty() ? f.source + ": frame " + std::to_string(t) : f.files[t];
      ThrowInputError(offending, ": frame is ", f.rgb[t].cols, "x", f.rgb[t].rows, ", but ", first,
                      " is ", f.width, "x", f.height,
                      " (every frame of a video must have the same size)");
    }
  }
  LOG(INFO) << "prepare: " << f.rgb.size() << " frames of " << f.width << "x" << f.height
            << " from " << f.source;
  return f;
}

// The raw mask images (CV_8UC1, frame size) and their files.
struct RawMasks {
  std::vector<cv::Mat> images;
  std::vector<fs::path> files;
};

RawMasks ReadMasks(const PrepareOptions& options, const RawFrames& frames) {
  const int n = static_cast<int>(frames.rgb.size());
  RawMasks out;
  out.files =
      MatchToFrames(ListFiles(options.masks_dir, {".png", ".bmp", ".jpg", ".jpeg"}, "mask images"),
                    frames.stems, n, options.masks_dir, "mask");
  out.images.resize(n);
  for (int t = 0; t < n; ++t) {
    const std::string file = out.files[t].string();
    cv::Mat& m = out.images[t];
    m = cv::imread(file, cv::IMREAD_GRAYSCALE);
    if (m.empty()) ThrowInputError(file, ": unreadable mask image");
    if (m.cols == frames.width && m.rows == frames.height) continue;
    const std::string frame = frames.files.empty() ? "frame " + std::to_string(t) : frames.files[t];
    if (!options.resize_masks) {
      ThrowInputError(file, ": mask is ", m.cols, "x", m.rows, ", its frame (", frame, ") is ",
                      frames.width, "x", frames.height,
                      " (masks must have the frames' size; --resize-masks scales them)");
    }
    if (t == 0) {
      LOG(WARNING) << "prepare: resizing masks from " << m.cols << "x" << m.rows << " to "
                   << frames.width << "x" << frames.height << " (nearest neighbour)";
    }
    cv::resize(m, m, cv::Size(frames.width, frames.height), 0, 0, cv::INTER_NEAREST);
  }
  return out;
}

// The mask format to use (detected for kAuto) and whether binary masks are 0/1.
MaskFormat DetectMaskFormat(const RawMasks& masks, MaskFormat format, bool* binary_01) {
  // Which values occur (for auto detection and the 0/1 reading).
  std::array<bool, 256> used{};
  std::array<int, 256> first_file{};
  for (std::size_t t = 0; t < masks.images.size(); ++t) {
    const cv::Mat& m = masks.images[t];
    for (int r = 0; r < m.rows; ++r) {
      const unsigned char* p = m.ptr<unsigned char>(r);
      for (int c = 0; c < m.cols; ++c) {
        if (!used[p[c]]) first_file[p[c]] = static_cast<int>(t);
        used[p[c]] = true;
      }
    }
  }
  int max_value = 0;
  for (int v = 255; v >= 0; --v) {
    if (used[v]) {
      max_value = v;
      break;
    }
  }
  if (format == MaskFormat::kAuto) {
    for (int v = 0; v < 256; ++v) {
      if (used[v] && v != 0 && v != 1 && v != 128 && v != 255) {
        ThrowInputError(masks.files[first_file[v]].string(), ": mask value ", v,
                        " is not 0, 1, 128 or 255, so the mask format cannot be detected "
                        "(use --mask-format binary to threshold at 128, or banmo)");
      }
    }
    format = used[128] ? MaskFormat::kBanmo : MaskFormat::kBinary;
    LOG(INFO) << "prepare: mask format detected: "
              << (format == MaskFormat::kBanmo ? "BANMo (128 = object, 255 = ignore)"
                                               : (max_value <= 1 ? "binary 0/1" : "binary 0/255"));
  }
  *binary_01 = format == MaskFormat::kBinary && max_value <= 1;
  return format;
}

// Reads one feature file: float16, zero outside the mask.
cv::Mat ReadFeatures(const std::string& path, const cv::Mat& mask) {
  const int w = mask.cols, h = mask.rows;
  const cv::Mat m = ReadNpy(path);
  if ((m.depth() != CV_16F && m.depth() != CV_32F) || m.channels() != kFeatureDim || m.cols != w ||
      m.rows != h) {
    ThrowInputError(path, ": expected a float16 or float32 array of shape (", h, ", ", w, ", ",
                    kFeatureDim, ")");
  }
  cv::Vec3i bad;
  if (!AllFinite(m, &bad))
    ThrowInputError(path, ": NaN or Inf at (x=", bad[1], ", y=", bad[0], ")");
  cv::Mat half;
  m.convertTo(half, CV_16F);
  // Zero outside the mask (cv::Mat::setTo takes at most 4 channels).
  const std::size_t pixel_bytes = half.elemSize();
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      if (mask.at<unsigned char>(r, c) == kMaskBackground) {
        std::memset(half.ptr(r) + c * pixel_bytes, 0, pixel_bytes);
      }
    }
  }
  return half;
}

// Fills the frames of `video` (rgb, mask, pose, features; no flow yet).
void BuildFrames(const PrepareOptions& options, const RawFrames& frames, const RawMasks& masks,
                 Video* video) {
  const int n = static_cast<int>(frames.rgb.size());
  bool binary_01 = false;
  const MaskFormat format = DetectMaskFormat(masks, options.mask_format, &binary_01);
  std::vector<fs::path> feature_files;
  if (!options.features_dir.empty()) {
    feature_files = MatchToFrames(ListFiles(options.features_dir, {".npy"}, "feature .npy files"),
                                  frames.stems, n, options.features_dir, "feature");
  }
  std::vector<Pose> poses;
  if (!options.poses_path.empty()) poses = ReadPoseFile(options.poses_path, n);
  video->frames.resize(n);
  std::vector<std::exception_ptr> errors(n);
  ParallelFor(n, [&](int begin, int end) {
    for (int t = begin; t < end; ++t) {
      try {
        Frame& f = video->frames[t];
        f.index = t;
        f.rgb = frames.rgb[t];
        f.mask = ConvertMask(masks.images[t], format, binary_01, masks.files[t].string());
        if (cv::countNonZero(f.mask == kMaskObject) == 0) {
          LOG(WARNING) << masks.files[t].string() << ": empty mask (no object pixel); frame " << t
                       << " will be skipped";
          f.skip = true;
        }
        if (poses.empty()) {
          f.root_pose_init = PoseIdentity();
          f.root_pose_init[kPoseT + 2] = options.default_distance;
        } else {
          f.root_pose_init = poses[t];
        }
        if (!feature_files.empty()) f.features = ReadFeatures(feature_files[t].string(), f.mask);
      } catch (...) {
        errors[t] = std::current_exception();
      }
    }
  });
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  int usable = 0;
  for (const Frame& f : video->frames) usable += f.skip ? 0 : 1;
  if (usable < 2) {
    ThrowInputError(frames.source, ": only ", usable, " usable frame(s) of ", n,
                    " (a frame is usable when its mask has an object pixel); a video needs at "
                    "least 2 (masks: ",
                    options.masks_dir, ")");
  }
}

// For each pair (t, t + g), forward and backward DIS flow, then the
// forward-backward check for both directions.
void ComputeFlows(const std::vector<int>& gaps, const OpticalFlowOptions& options,
                  const std::vector<cv::Mat>& rgb, Video* video) {
  struct Pair {
    int t;
    int gap;
  };
  const int n = static_cast<int>(rgb.size());
  std::vector<Pair> pairs;
  for (int g : gaps) {
    for (int t = 0; t + g < n; ++t) pairs.push_back({t, g});
  }
  std::vector<FlowField> forward(pairs.size()), backward(pairs.size());
  ParallelFor(static_cast<int>(pairs.size()), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const int t = pairs[i].t;
      const int g = pairs[i].gap;
      const cv::Mat fw = ComputeDisFlow(rgb[t], rgb[t + g], options.preset);
      const cv::Mat bw = ComputeDisFlow(rgb[t + g], rgb[t], options.preset);
      forward[i].gap = g;
      forward[i].valid = ForwardBackwardValid(fw, bw, options);
      fw.convertTo(forward[i].flow, CV_16F);
      backward[i].gap = -g;
      backward[i].valid = ForwardBackwardValid(bw, fw, options);
      bw.convertTo(backward[i].flow, CV_16F);
    }
  });
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    video->frames[pairs[i].t].flows.push_back(std::move(forward[i]));
    video->frames[pairs[i].t + pairs[i].gap].flows.push_back(std::move(backward[i]));
  }
}

// The size of frames of width x height whose longer side is at most
// max_size (0: unchanged), rounded to whole pixels.
cv::Size WorkingSize(int width, int height, int max_size) {
  const int longer = std::max(width, height);
  if (max_size == 0 || longer <= max_size) return {width, height};
  const double s = static_cast<double>(max_size) / longer;
  return {std::max(1, static_cast<int>(std::lround(width * s))),
          std::max(1, static_cast<int>(std::lround(height * s)))};
}

// A mask scaled down by a vote over each output pixel's area: ignore where
// at least half of it is ignore, else object where at least half is
// object, else background.
cv::Mat DownsampleMask(const cv::Mat& mask, cv::Size size) {
  cv::Mat object, ignore;
  cv::Mat(mask == kMaskObject).convertTo(object, CV_32F, 1.0 / 255.0);
  cv::Mat(mask == kMaskIgnore).convertTo(ignore, CV_32F, 1.0 / 255.0);
  cv::resize(object, object, size, 0, 0, cv::INTER_AREA);
  cv::resize(ignore, ignore, size, 0, 0, cv::INTER_AREA);
  cv::Mat out(size, CV_8UC1);
  for (int r = 0; r < size.height; ++r) {
    for (int c = 0; c < size.width; ++c) {
      out.at<unsigned char>(r, c) = ignore.at<float>(r, c) >= 0.5f   ? kMaskIgnore
                                    : object.at<float>(r, c) >= 0.5f ? kMaskObject
                                                                     : kMaskBackground;
    }
  }
  return out;
}

// Scales the frames of `video` (rgb, mask, features) to `size` when they
// are larger; a frame whose mask loses its last object pixel is skipped.
void ScaleFrames(cv::Size size, const std::string& source, Video* video) {
  const int n = static_cast<int>(video->frames.size());
  ParallelFor(n, [&](int begin, int end) {
    for (int t = begin; t < end; ++t) {
      Frame& f = video->frames[t];
      cv::Mat rgb;
      cv::resize(f.rgb, rgb, size, 0, 0, cv::INTER_AREA);
      f.rgb = rgb;
      f.mask = DownsampleMask(f.mask, size);
      if (!f.features.empty()) {
        cv::Mat wide, small;
        f.features.convertTo(wide, CV_32F);
        cv::resize(wide, small, size, 0, 0, cv::INTER_AREA);
        small.convertTo(f.features, CV_16F);
        const std::size_t pixel_bytes = f.features.elemSize();
        for (int r = 0; r < size.height; ++r) {
          for (int c = 0; c < size.width; ++c) {
            if (f.mask.at<unsigned char>(r, c) == kMaskBackground) {
              std::memset(f.features.ptr(r) + c * pixel_bytes, 0, pixel_bytes);
            }
          }
        }
      }
    }
  });
  for (Frame& f : video->frames) {
    if (!f.skip && cv::countNonZero(f.mask == kMaskObject) == 0) {
      LOG(WARNING) << source << ": frame " << f.index
                   << ": no object pixel left at the working resolution; it will be skipped";
      f.skip = true;
    }
  }
  int usable = 0;
  for (const Frame& f : video->frames) usable += f.skip ? 0 : 1;
  if (usable < 2) {
    ThrowInputError(source, ": only ", usable,
                    " frame(s) keep an object pixel at the working size ", size.width, "x",
                    size.height, " (--max-size); a video needs at least 2");
  }
}

}  // namespace

void PlaceRootsOnMaskCentroids(double distance, bool depth_from_size, Video* video) {
  const Eigen::Vector4d& k = video->camera.intrinsics;
  const int n = static_cast<int>(video->frames.size());
  std::vector<int> placed;  // frames with object pixels
  std::vector<cv::Moments> moments(n);
  std::vector<double> areas;
  for (int t = 0; t < n; ++t) {
    moments[t] = cv::moments(video->frames[t].mask == kMaskObject, true);
    if (moments[t].m00 <= 0.0) continue;
    placed.push_back(t);
    areas.push_back(moments[t].m00);
  }
  if (placed.empty()) return;
  const double median_area = Median(std::move(areas));
  for (int t : placed) {
    const cv::Moments& m = moments[t];
    const double depth = depth_from_size
                             ? distance * std::clamp(std::sqrt(median_area / m.m00),
                                                     1.0 / kMaxRootDepthRatio, kMaxRootDepthRatio)
                             : distance;
    const double u = m.m10 / m.m00 + 0.5, v = m.m01 / m.m00 + 0.5;
    Frame& f = video->frames[t];
    f.root_pose_init[kPoseT + 0] = depth * (u - k[2]) / k[0];
    f.root_pose_init[kPoseT + 1] = depth * (v - k[3]) / k[1];
    f.root_pose_init[kPoseT + 2] = depth;
  }
  for (int t = 0; t < n; ++t) {
    const auto after = std::lower_bound(placed.begin(), placed.end(), t);
    if (after != placed.end() && *after == t) continue;
    int nearest;
    if (after == placed.end()) {
      nearest = placed.back();
    } else if (after == placed.begin()) {
      nearest = *after;
    } else {
      nearest = (t - *(after - 1) <= *after - t) ? *(after - 1) : *after;
    }
    for (int i = 0; i < 3; ++i) {
      video->frames[t].root_pose_init[kPoseT + i] =
          video->frames[nearest].root_pose_init[kPoseT + i];
    }
  }
}

Dataset PrepareDataset(const PrepareOptions& options) {
  options.Check();
  Timer timer;
  const RawFrames frames = ReadFrames(options);
  const RawMasks masks = ReadMasks(options, frames);
  Dataset dataset;
  dataset.flow_gaps = options.gaps;
  std::sort(dataset.flow_gaps.begin(), dataset.flow_gaps.end());
  Video& video = dataset.videos.emplace_back();
  video.name = options.video_name;
  const cv::Size size = WorkingSize(frames.width, frames.height, options.max_size);
  video.camera.width = size.width;
  video.camera.height = size.height;
  const double focal = std::max(size.width, size.height);
  // Given intrinsics are of the frames as read: pixel coordinates scale with
  // the image (the pixel (x, y) covers [x, x + 1) x [y, y + 1)).
  const double sx = static_cast<double>(size.width) / frames.width;
  const double sy = static_cast<double>(size.height) / frames.height;
  video.camera.intrinsics =
      options.intrinsics
          ? Eigen::Vector4d(sx * (*options.intrinsics)[0], sy * (*options.intrinsics)[1],
                            sx * (*options.intrinsics)[2], sy * (*options.intrinsics)[3])
          : Eigen::Vector4d(focal, focal, size.width / 2.0, size.height / 2.0);
  BuildFrames(options, frames, masks, &video);
  std::vector<cv::Mat> rgb = frames.rgb;
  if (size.width != frames.width || size.height != frames.height) {
    LOG(INFO) << "prepare: frames scaled from " << frames.width << "x" << frames.height << " to "
              << size.width << "x" << size.height << " (max size " << options.max_size << ")";
    ScaleFrames(size, frames.source, &video);
    for (int t = 0; t < static_cast<int>(rgb.size()); ++t) rgb[t] = video.frames[t].rgb;
  }
  if (options.poses_path.empty() && options.roots_on_mask_centroids) {
    PlaceRootsOnMaskCentroids(options.default_distance, options.roots_depth_from_mask_size, &video);
  }
  ComputeFlows(dataset.flow_gaps, options.flow, rgb, &video);
  LOG(INFO) << "prepare: flow for " << dataset.flow_gaps.size() << " gaps in " << timer.Seconds()
            << " s";
  if (options.poses_path.empty() && options.roots_turn_with_camera) {
    if (std::find(dataset.flow_gaps.begin(), dataset.flow_gaps.end(), 1) ==
        dataset.flow_gaps.end()) {
      LOG(WARNING) << "prepare: no flow gap 1 (--gaps): root rotations not turned with the camera";
    } else {
      const CameraRotations rotations = EstimateCameraRotations(video, options.camera_rotation);
      RotateRootsWithCamera(rotations, &video);
      const double total_deg =
          Eigen::AngleAxisd(rotations.camera_from_first.back()).angle() * 180.0 / M_PI;
      LOG(INFO) << "prepare: camera rotation from the background's flow: " << total_deg
                << " deg from the first frame to the last; "
                << rotations.step_ok.size() - rotations.FailedSteps() << " of "
                << rotations.step_ok.size() << " steps fitted (" << rotations.EssentialSteps()
                << " with parallax, by the essential matrix; the unfitted taken as no turn)";
    }
  }
  return dataset;
}

}  // namespace banmo
