// WriteDataset: validates the in-memory dataset, writes everything into a
// temporary folder beside the target and renames it into place.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>
#include <vector>

#include "banmo/geometry/mesh_io.h"
#include "banmo/io/codecs.h"
#include "banmo/io/dataset.h"
#include "banmo/io/npy.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"
#include "manifest.h"

namespace banmo {
namespace fs = std::filesystem;
namespace {

std::string FrameWhere(const Video& video, int t) {
  return "WriteDataset: video '" + video.name + "' frame " + std::to_string(t);
}

// Expected signed gaps of frame t in a video of n frames.
std::set<int> ExpectedGaps(const std::vector<int>& gaps, int t, int n) {
  std::set<int> out;
  for (int g : gaps) {
    if (t + g < n) out.insert(g);
    if (t - g >= 0) out.insert(-g);
  }
  return out;
}

// Checks the in-memory video and returns its manifest entry.
internal::ManifestVideo CheckVideo(const Dataset& dataset, const Video& video, int v,
                                   const std::vector<std::vector<TriangleMesh>>* gt_meshes) {
  internal::CheckVideoName(video.name, "WriteDataset: video " + std::to_string(v));
  const std::string where = "WriteDataset: video '" + video.name + "'";
  const int n = static_cast<int>(video.frames.size());
  if (n == 0) ThrowInputError(where, ": has no frames");
  if (n > 100000) ThrowInputError(where, ": more than 100000 frames");
  const PinholeCamera& cam = video.camera;
  if (cam.width <= 0 || cam.height <= 0) {
    ThrowInputError(where, ": camera size ", cam.width, "x", cam.height, " is not positive");
  }
  internal::CheckIntrinsics(cam.intrinsics, cam.width, cam.height, where);
  internal::ManifestVideo mv;
  mv.name = video.name;
  mv.frames = n;
  mv.width = cam.width;
  mv.height = cam.height;
  mv.intrinsics = cam.intrinsics;
  if (video.intrinsics_gt) {
    internal::CheckIntrinsics(*video.intrinsics_gt, cam.width, cam.height,
                              where + " (intrinsics_gt)");
    mv.intrinsics_gt = video.intrinsics_gt;
  }
  const Frame& f0 = video.frames[0];
  mv.present.features = !f0.features.empty();
  mv.present.flow = !f0.flows.empty();
  mv.present.depth = !f0.depth.empty();
  mv.present.root_poses_gt = f0.root_pose_gt.has_value();
  mv.present.gt_mesh = gt_meshes != nullptr || !f0.gt_mesh_path.empty();
  mv.present.mask_gt = !f0.mask_gt.empty();
  // Video::present (set by LoadDataset) claims data the frames do not hold:
  // most likely loaded with LoadOptions that skipped it. Refuse rather than
  // silently drop it.
  const VideoContents& claimed = video.present;
  const char* dropped = claimed.features && !mv.present.features             ? "features"
                        : claimed.flow && !mv.present.flow                   ? "flow"
                        : claimed.depth && !mv.present.depth                 ? "depth"
                        : claimed.gt_mesh && !mv.present.gt_mesh             ? "gt_mesh"
                        : claimed.root_poses_gt && !mv.present.root_poses_gt ? "root_poses_gt"
                        : claimed.mask_gt && !mv.present.mask_gt             ? "mask_gt"
                                                                             : nullptr;
  if (dropped != nullptr) {
    ThrowInputError(where, ": Video::present lists ", dropped,
                    " but the frames do not hold it (loaded with LoadOptions that skip it?); "
                    "load everything or clear the flag to drop it");
  }
  if (gt_meshes != nullptr && static_cast<int>((*gt_meshes)[v].size()) != n) {
    ThrowInputError(where, ": gt_meshes has ", (*gt_meshes)[v].size(), " meshes for ", n,
                    " frames");
  }
  if (mv.present.flow && dataset.flow_gaps.empty()) {
    ThrowInputError(where, ": frames hold flow but Dataset::flow_gaps is empty");
  }
  const cv::Size size(cam.width, cam.height);
  for (int t = 0; t < n; ++t) {
    const Frame& f = video.frames[t];
    const std::string fw = FrameWhere(video, t);
    if (f.index != t) ThrowInputError(fw, ": Frame::index is ", f.index, ", expected ", t);
    if (f.rgb.type() != CV_8UC3 || f.rgb.size() != size) {
      ThrowInputError(fw, ": rgb must be CV_8UC3 of ", cam.width, "x", cam.height);
    }
    if (f.mask.type() != CV_8UC1 || f.mask.size() != size) {
      ThrowInputError(fw, ": mask must be CV_8UC1 of ", cam.width, "x", cam.height);
    }
    if (mv.present.features != !f.features.empty() || mv.present.flow != !f.flows.empty() ||
        mv.present.depth != !f.depth.empty() || mv.present.mask_gt != !f.mask_gt.empty() ||
        mv.present.root_poses_gt != f.root_pose_gt.has_value() ||
        (gt_meshes == nullptr && mv.present.gt_mesh == f.gt_mesh_path.empty())) {
      ThrowInputError(
          fw,
          ": has a different set of data (features, flow, depth, mask_gt, "
          "root_pose_gt, gt_mesh_path) than frame 0; every frame of a video must have the same");
    }
    if (mv.present.features && (f.features.size() != size || f.features.channels() != kFeatureDim ||
                                (f.features.depth() != CV_16F && f.features.depth() != CV_32F))) {
      ThrowInputError(fw, ": features must be CV_16FC(", kFeatureDim, ") of ", cam.width, "x",
                      cam.height);
    }
    if (mv.present.mask_gt && (f.mask_gt.type() != CV_8UC1 || f.mask_gt.size() != size)) {
      ThrowInputError(fw, ": mask_gt must be CV_8UC1 of ", cam.width, "x", cam.height);
    }
    if (mv.present.depth && (f.depth.type() != CV_32FC1 || f.depth.size() != size)) {
      ThrowInputError(fw, ": depth must be CV_32FC1 of ", cam.width, "x", cam.height);
    }
    if (!f.root_pose_init.allFinite() ||
        (f.root_pose_gt.has_value() && !f.root_pose_gt->allFinite())) {
      ThrowInputError(fw, ": non-finite root pose");
    }
    if (mv.present.flow) {
      const std::set<int> expected = ExpectedGaps(dataset.flow_gaps, t, n);
      std::set<int> found;
      for (const FlowField& ff : f.flows) {
        if (!found.insert(ff.gap).second || expected.count(ff.gap) == 0) {
          ThrowInputError(fw, ": unexpected or duplicate flow for gap ", ff.gap,
                          " (expected one per gap +-g of flow_gaps within the video)");
        }
        if ((ff.flow.type() != CV_16FC2 && ff.flow.type() != CV_32FC2) || ff.flow.size() != size ||
            ff.valid.type() != CV_8UC1 || ff.valid.size() != size) {
          ThrowInputError(fw, ": flow for gap ", ff.gap, " must be CV_16FC2 + CV_8UC1 valid of ",
                          cam.width, "x", cam.height);
        }
      }
      if (found.size() != expected.size()) {
        ThrowInputError(fw, ": has ", found.size(), " flow fields, expected ", expected.size(),
                        " (forward and backward for each gap that stays inside the video)");
      }
    }
  }
  return mv;
}

double ChooseDepthUnit(const Dataset& dataset) {
  double max_depth = 0.0;
  for (const Video& v : dataset.videos) {
    for (const Frame& f : v.frames) {
      if (f.depth.empty()) continue;
      double lo = 0, hi = 0;
      cv::minMaxLoc(f.depth, &lo, &hi);
      max_depth = std::max(max_depth, hi);
    }
  }
  for (int k = -5; k < 10; ++k) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double unit = m * std::pow(10.0, k);
      if (max_depth / unit <= 65535.0) return unit;
    }
  }
  return 1e10;
}

void WriteImage(const std::string& path, const cv::Mat& image, int compression) {
  const std::vector<int> params = {cv::IMWRITE_PNG_COMPRESSION, compression};
  bool ok = false;
  try {
    ok = cv::imwrite(path, image, params);
  } catch (const cv::Exception& e) {
    ThrowInputError(path, ": could not write image: ", e.what());
  }
  if (!ok) ThrowInputError(path, ": could not write image");
}

void WriteFrame(const Dataset& dataset, const Video& video, int t, const std::string& vdir,
                const internal::ManifestVideo& mv, const internal::Manifest& manifest,
                const WriteOptions& options, const TriangleMesh* gt_mesh) {
  const Frame& f = video.frames[t];
  const std::string fw = FrameWhere(video, t);
  const std::string png = FrameFileName(t, "png");
  const std::string npy = FrameFileName(t, "npy");
  cv::Mat bgr;
  cv::cvtColor(f.rgb, bgr, cv::COLOR_RGB2BGR);
  WriteImage(vdir + "/rgb/" + png, bgr, options.png_compression);
  for (int r = 0; r < f.mask.rows; ++r) {
    const unsigned char* m = f.mask.ptr<unsigned char>(r);
    for (int c = 0; c < f.mask.cols; ++c) {
      if (m[c] != kMaskBackground && m[c] != kMaskIgnore && m[c] != kMaskObject) {
        ThrowInputError(fw, ": mask value ", int(m[c]), " at (x=", c, ", y=", r,
                        ") is not 0, 128 or 255");
      }
    }
  }
  WriteImage(vdir + "/mask/" + png, f.mask, options.png_compression);
  if (mv.present.mask_gt) {
    for (int r = 0; r < f.mask_gt.rows; ++r) {
      const unsigned char* m = f.mask_gt.ptr<unsigned char>(r);
      for (int c = 0; c < f.mask_gt.cols; ++c) {
        if (m[c] != kMaskBackground && m[c] != kMaskIgnore && m[c] != kMaskObject) {
          ThrowInputError(fw, ": mask_gt value ", int(m[c]), " at (x=", c, ", y=", r,
                          ") is not 0, 128 or 255");
        }
      }
    }
    WriteImage(vdir + "/mask_gt/" + png, f.mask_gt, options.png_compression);
  }
  if (mv.present.features) {
    cv::Mat half = f.features;
    if (half.depth() != CV_16F) f.features.convertTo(half, CV_16F);
    cv::Vec3i bad;
    if (!AllFinite(half, &bad)) {
      ThrowInputError(fw, ": non-finite feature at (x=", bad[1], ", y=", bad[0], ", channel ",
                      bad[2], ")");
    }
    WriteFileAtomic(vdir + "/features/" + npy, EncodeNpy(half));
  }
  for (const FlowField& ff : f.flows) {
    const std::string folder =
        vdir + "/flow/" + (ff.gap > 0 ? "fw_" : "bw_") + std::to_string(std::abs(ff.gap)) + "/";
    cv::Vec3i bad;
    if (!AllFinite(ff.flow, &bad)) {
      ThrowInputError(fw, ": non-finite flow (gap ", ff.gap, ") at (x=", bad[1], ", y=", bad[0],
                      ")");
    }
    if (manifest.flow_encoding == FlowEncoding::kKittiPng16) {
      int clamped = 0;
      const cv::Mat encoded = EncodeFlowKitti(ff.flow, ff.valid, &clamped);
      if (clamped > 0) {
        LOG(WARNING) << fw << ": " << clamped << " flow vectors (gap " << ff.gap
                     << ") outside [-512, 512) px were clamped and marked invalid";
      }
      WriteImage(folder + png, encoded, options.png_compression);
    } else {
      cv::Mat flow32, valid32;
      ff.flow.convertTo(flow32, CV_32F);
      ff.valid.convertTo(valid32, CV_32F, 1.0 / 255.0);
      cv::Mat uvw;
      cv::merge(std::vector<cv::Mat>{flow32, valid32}, uvw);
      cv::Mat half;
      uvw.convertTo(half, CV_16F);
      WriteFileAtomic(folder + npy, EncodeNpy(half));
    }
  }
  if (mv.present.depth) {
    if (!AllFinite(f.depth) || cv::checkRange(f.depth, true, nullptr, 0.0) == false) {
      ThrowInputError(fw, ": depth must be finite and >= 0");
    }
    if (manifest.depth_encoding == DepthEncoding::kPng16) {
      cv::Mat d16;
      f.depth.convertTo(d16, CV_16U, 1.0 / manifest.depth_unit);  // rounds, saturates
      WriteImage(vdir + "/depth/" + png, d16, options.png_compression);
    } else {
      WriteFileAtomic(vdir + "/depth/" + npy, EncodeNpy(f.depth, false));
    }
  }
  if (mv.present.gt_mesh) {
    const std::string target = vdir + "/gt_mesh/" + FrameFileName(t, "ply");
    if (gt_mesh != nullptr) {
      WritePly(target, *gt_mesh);
    } else {
      std::error_code ec;
      fs::copy_file(f.gt_mesh_path, target, ec);
      if (ec) ThrowInputError(f.gt_mesh_path, ": could not copy the GT mesh: ", ec.message());
    }
  }
}

}  // namespace

void WriteOptions::Check() const {
  if (png_compression < 0 || png_compression > 9) {
    ThrowInputError("WriteOptions::png_compression = ", png_compression, ", expected 0..9");
  }
  if (!std::isfinite(depth_unit)) ThrowInputError("WriteOptions::depth_unit must be finite");
}

void WriteDataset(const Dataset& dataset, const std::string& dir,
                  const std::vector<std::vector<TriangleMesh>>* gt_meshes, bool overwrite) {
  WriteOptions options;
  options.overwrite = overwrite;
  WriteDataset(dataset, dir, options, gt_meshes);
}

namespace {

// The manifest of `dataset`, after checking everything in memory (nothing is
// written for a bad dataset).
internal::Manifest CheckedManifest(const Dataset& dataset, const WriteOptions& options,
                                   const std::vector<std::vector<TriangleMesh>>* gt_meshes) {
  if (dataset.videos.empty()) ThrowInputError("WriteDataset: the dataset has no videos");
  if (gt_meshes != nullptr && gt_meshes->size() != dataset.videos.size()) {
    ThrowInputError("WriteDataset: gt_meshes has ", gt_meshes->size(), " videos, the dataset ",
                    dataset.videos.size());
  }
  internal::Manifest manifest;
  manifest.flow_gaps = dataset.flow_gaps;
  std::sort(manifest.flow_gaps.begin(), manifest.flow_gaps.end());
  for (int g : manifest.flow_gaps) {
    if (g <= 0 || g >= 100000) ThrowInputError("WriteDataset: bad flow gap ", g);
  }
  if (std::adjacent_find(manifest.flow_gaps.begin(), manifest.flow_gaps.end()) !=
      manifest.flow_gaps.end()) {
    ThrowInputError("WriteDataset: duplicate flow gap");
  }
  manifest.flow_encoding = options.flow_encoding;
  manifest.depth_encoding = options.depth_encoding;
  std::set<std::string> names;
  bool any_depth = false;
  for (int v = 0; v < static_cast<int>(dataset.videos.size()); ++v) {
    manifest.videos.push_back(CheckVideo(dataset, dataset.videos[v], v, gt_meshes));
    if (!names.insert(dataset.videos[v].name).second) {
      ThrowInputError("WriteDataset: duplicate video name '", dataset.videos[v].name, "'");
    }
    any_depth |= manifest.videos.back().present.depth;
  }
  if (any_depth && options.depth_encoding == DepthEncoding::kPng16) {
    manifest.depth_unit = options.depth_unit > 0 ? options.depth_unit : ChooseDepthUnit(dataset);
  }
  return manifest;
}

// The normalised target folder: must not exist, be an empty folder, or
// overwrite must be set.
fs::path CheckedTarget(const std::string& dir, bool overwrite) {
  fs::path target = fs::path(dir).lexically_normal();
  if (target.filename().empty()) target = target.parent_path();
  std::error_code ec;
  if (fs::exists(target, ec)) {
    if (!fs::is_directory(target, ec)) {
      ThrowInputError(target.string(), ": exists and is not a folder");
    }
    if (!fs::is_empty(target, ec) && !overwrite) {
      ThrowInputError(target.string(),
                      ": folder exists and is not empty (choose another folder or overwrite)");
    }
  }
  return target;
}

// Writes the manifest, the folders and pose files of every video and then
// every frame (in parallel) into `temp`.
void WriteContents(const Dataset& dataset, const internal::Manifest& manifest,
                   const WriteOptions& options,
                   const std::vector<std::vector<TriangleMesh>>* gt_meshes,
                   const std::string& temp) {
  WriteFileAtomic(temp + "/" + internal::kManifestName, internal::EmitManifest(manifest));
  struct Job {
    int video;
    int frame;
  };
  std::vector<Job> jobs;
  for (int v = 0; v < static_cast<int>(dataset.videos.size()); ++v) {
    const Video& video = dataset.videos[v];
    const internal::ManifestVideo& mv = manifest.videos[v];
    const std::string vdir = temp + "/" + video.name;
    MakeDirectories(vdir + "/rgb");
    MakeDirectories(vdir + "/mask");
    if (mv.present.features) MakeDirectories(vdir + "/features");
    if (mv.present.depth) MakeDirectories(vdir + "/depth");
    if (mv.present.gt_mesh) MakeDirectories(vdir + "/gt_mesh");
    if (mv.present.mask_gt) MakeDirectories(vdir + "/mask_gt");
    if (mv.present.flow) {
      for (int g : manifest.flow_gaps) {
        MakeDirectories(vdir + "/flow/fw_" + std::to_string(g));
        MakeDirectories(vdir + "/flow/bw_" + std::to_string(g));
      }
    }
    std::vector<Pose> init, gt;
    for (const Frame& f : video.frames) {
      init.push_back(f.root_pose_init);
      if (f.root_pose_gt) gt.push_back(*f.root_pose_gt);
    }
    WritePoseFile(vdir + "/" + internal::kPosesInitName, init, video.root_poses_init_comment);
    if (mv.present.root_poses_gt) WritePoseFile(vdir + "/" + internal::kPosesGtName, gt);
    for (int t = 0; t < mv.frames; ++t) jobs.push_back({v, t});
  }
  std::vector<std::exception_ptr> errors(jobs.size());
  ParallelFor(static_cast<int>(jobs.size()), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const int v = jobs[i].video;
      const int t = jobs[i].frame;
      try {
        WriteFrame(dataset, dataset.videos[v], t, temp + "/" + dataset.videos[v].name,
                   manifest.videos[v], manifest, options,
                   gt_meshes != nullptr ? &(*gt_meshes)[v][t] : nullptr);
      } catch (...) {
        errors[i] = std::current_exception();
        return;  // stop this chunk at its first error
      }
    }
  });
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

// Flushes our files and folders (fsync each: unlike syncfs this does not
// wait for other programs' dirty data on the same file system).
void SyncTree(const std::string& dir) {
  std::error_code ec;
  std::vector<std::string> to_sync;
  for (auto it = fs::recursive_directory_iterator(dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    to_sync.push_back(it->path().string());
  }
  to_sync.push_back(dir);
  ParallelFor(static_cast<int>(to_sync.size()), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const int fd = ::open(to_sync[i].c_str(), O_RDONLY);
      if (fd >= 0) {
        ::fsync(fd);
        ::close(fd);
      }
    }
  });
}

// Puts `temp` in place of `target`. An existing (empty or, with overwrite,
// old) folder is moved aside first and removed only after the rename
// succeeded.
void MoveIntoPlace(const std::string& temp, const fs::path& target, std::random_device* rd) {
  std::error_code ec;
  std::string old;
  if (fs::exists(target, ec)) {
    old = target.string() + ".old-" + std::to_string(::getpid()) + "-" +
          std::to_string((*rd)() % 1000000);
    fs::rename(target, old, ec);
    if (ec) {
      ThrowInputError(target.string(), ": could not move the old folder aside: ", ec.message());
    }
  }
  fs::rename(temp, target, ec);
  if (ec) {
    const std::string reason = ec.message();
    if (!old.empty()) fs::rename(old, target, ec);  // restore
    ThrowInputError(target.string(), ": could not rename the written dataset into place: ", reason);
  }
  if (!old.empty()) fs::remove_all(old, ec);
  const std::string parent =
      target.parent_path().empty() ? std::string(".") : target.parent_path().string();
  const int parent_fd = ::open(parent.c_str(), O_RDONLY | O_DIRECTORY);
  if (parent_fd >= 0) {
    ::fsync(parent_fd);  // make the rename durable
    ::close(parent_fd);
  }
}

// What a killed WriteDataset left beside `target`: `<target>.tmp-<pid>-<n>`
// folders (a dataset being written) are removed; a `<target>.old-<pid>-<n>`
// folder (killed between MoveIntoPlace's two renames) is moved back when
// the target is missing (the old dataset is restored), else removed. Only
// folders of processes that are gone are touched.
void RecoverKilledWrite(const fs::path& target) {
  const std::string base = target.filename().string();
  if (base.empty() || base == "." || base == "..") return;
  const fs::path parent = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  std::error_code ec;
  std::vector<fs::path> temps, olds;
  for (const auto& entry : fs::directory_iterator(parent, ec)) {
    const std::string name = entry.path().filename().string();
    for (const char* kind : {".tmp-", ".old-"}) {
      const std::string prefix = base + kind;
      if (name.rfind(prefix, 0) != 0 || !entry.is_directory(ec)) continue;
      char* end = nullptr;
      const std::string rest = name.substr(prefix.size());
      const long pid = std::strtol(rest.c_str(), &end, 10);
      if (end == rest.c_str() || *end != '-' || ProcessMayBeAlive(pid)) continue;
      (kind[1] == 't' ? temps : olds).push_back(entry.path());
    }
  }
  for (const fs::path& old : olds) {
    if (!fs::exists(target, ec)) {
      fs::rename(old, target, ec);
      if (!ec) {
        LOG(WARNING) << target.string() << ": restored from " << old.string()
                     << " (a write of this dataset was killed between its renames)";
        continue;
      }
    }
    fs::remove_all(old, ec);
  }
  for (const fs::path& temp : temps) {
    fs::remove_all(temp, ec);
    LOG(WARNING) << "removed " << temp.string() << " (a killed write of " << target.string() << ")";
  }
}

}  // namespace

void WriteDataset(const Dataset& dataset, const std::string& dir, const WriteOptions& options,
                  const std::vector<std::vector<TriangleMesh>>* gt_meshes) {
  options.Check();
  if (dir.empty()) ThrowInputError("WriteDataset: empty output folder name");
  const internal::Manifest manifest = CheckedManifest(dataset, options, gt_meshes);
  {
    fs::path normal = fs::path(dir).lexically_normal();
    if (normal.filename().empty()) normal = normal.parent_path();
    RecoverKilledWrite(normal);
  }
  const fs::path target = CheckedTarget(dir, options.overwrite);
  if (!target.parent_path().empty()) MakeDirectories(target.parent_path().string());
  std::random_device rd;
  const std::string temp =
      target.string() + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(rd() % 1000000);
  MakeDirectories(temp);
  try {
    WriteContents(dataset, manifest, options, gt_meshes, temp);
    SyncTree(temp);
    MoveIntoPlace(temp, target, &rd);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(temp, ec);
    throw;
  }
}

}  // namespace banmo
