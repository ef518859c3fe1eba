// LoadDataset: validates the folder structure against the manifest, then
// loads and checks every frame in parallel.
#include <algorithm>
#include <exception>
#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <set>

#include "banmo/io/codecs.h"
#include "banmo/io/dataset.h"
#include "banmo/io/npy.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"
#include "manifest.h"

namespace banmo {
namespace fs = std::filesystem;
namespace {

// Compares a folder's entries with the expected names. `files` are regular
// files, `dirs` folders. Errors name the first missing or unexpected entry;
// for frame folders (frame_count >= 0) they also state the frame counts.
void CheckListing(const std::string& folder, const std::set<std::string>& files,
                  const std::set<std::string>& dirs, const std::string& what,
                  int frame_count = -1) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) ThrowInputError(folder, ": missing folder (", what, ")");
  std::set<std::string> found_files, found_dirs;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    if (entry.is_directory(ec)) {
      found_dirs.insert(name);
    } else {
      found_files.insert(name);
    }
  }
  if (ec) ThrowInputError(folder, ": cannot list folder: ", ec.message());
  const std::string count_note = frame_count >= 0 && found_files.size() != files.size()
                                     ? " (found " + std::to_string(found_files.size()) +
                                           " files for " + std::to_string(frame_count) +
                                           " frames in the manifest: frame-count mismatch)"
                                     : "";
  for (const std::string& f : files) {
    if (found_dirs.count(f)) ThrowInputError(folder, "/", f, ": expected a file, found a folder");
    if (!found_files.count(f)) {
      ThrowInputError(folder, "/", f, ": missing file (", what, ")", count_note);
    }
  }
  for (const std::string& d : dirs) {
    if (found_files.count(d)) ThrowInputError(folder, "/", d, ": expected a folder, found a file");
    if (!found_dirs.count(d)) ThrowInputError(folder, "/", d, ": missing folder (", what, ")");
  }
  for (const std::string& f : found_files) {
    if (!files.count(f)) {
      ThrowInputError(folder, "/", f, ": unexpected file (", what, ")", count_note);
    }
  }
  for (const std::string& d : found_dirs) {
    if (!dirs.count(d)) ThrowInputError(folder, "/", d, ": unexpected folder (", what, ")");
  }
}

std::set<std::string> FrameFiles(int begin, int end, const std::string& ext) {
  std::set<std::string> out;
  for (int t = begin; t < end; ++t) out.insert(FrameFileName(t, ext));
  return out;
}

// Checks a float image read from .npy: type, size, channels, finiteness.
cv::Mat CheckNpyImage(const cv::Mat& m, const std::string& path, int depth, int channels,
                      const internal::ManifestVideo& mv, const char* expected) {
  if (m.depth() != depth || m.channels() != channels) {
    ThrowInputError(path, ": expected ", expected);
  }
  if (m.cols != mv.width || m.rows != mv.height) {
    ThrowInputError(path, ": array size ", m.cols, "x", m.rows, " does not match ", mv.width, "x",
                    mv.height, " (width x height of video '", mv.name, "'), expected ", expected);
  }
  cv::Vec3i bad;
  if (!AllFinite(m, &bad)) {
    ThrowInputError(path, ": NaN or Inf at (x=", bad[1], ", y=", bad[0], ", channel ", bad[2],
                    "), expected finite values");
  }
  return m;
}

void CheckNpyHeaderOnly(const std::string& path, const char* descr,
                        const std::vector<std::int64_t>& shape, const char* expected) {
  const NpyHeader h = ReadNpyHeader(path);
  if (h.descr != descr || h.shape != shape) {
    ThrowInputError(path, ": expected ", expected);
  }
}

void LoadFrame(const internal::Manifest& manifest, const internal::ManifestVideo& mv,
               const std::string& vdir, const LoadOptions& options, Frame* frame) {
  const int t = frame->index;
  const int n = mv.frames;
  const int w = mv.width;
  const int h = mv.height;
  const std::string png = FrameFileName(t, "png");
  const std::string npy = FrameFileName(t, "npy");

  {
    const std::string path = vdir + "/rgb/" + png;
    const cv::Mat bgr = DecodePngStrict(ReadFileBytes(path), path, CV_8U, 3, w, h);
    cv::cvtColor(bgr, frame->rgb, cv::COLOR_BGR2RGB);
  }
  {
    const std::string path = vdir + "/mask/" + png;
    frame->mask = DecodePngStrict(ReadFileBytes(path), path, CV_8U, 1, w, h);
    int object = 0;
    for (int r = 0; r < h; ++r) {
      const unsigned char* m = frame->mask.ptr<unsigned char>(r);
      for (int c = 0; c < w; ++c) {
        if (m[c] == kMaskObject) {
          ++object;
        } else if (m[c] != kMaskBackground && m[c] != kMaskIgnore) {
          ThrowInputError(path, ": mask value ", int(m[c]), " at (x=", c, ", y=", r,
                          "), expected 0 (background), 128 (ignore) or 255 (object)");
        }
      }
    }
    if (object == 0) {
      LOG(WARNING) << path << ": empty mask (no object pixel); frame " << t << " of video '"
                   << mv.name << "' is skipped";
      frame->skip = true;
    }
  }
  const char* feature_expect = "a float16 ('<f2') array of shape (height, width, 16)";
  if (mv.present.features) {
    const std::string path = vdir + "/features/" + npy;
    if (options.load_features) {
      const cv::Mat m = ReadNpy(path);
      if (m.dims == 2 && m.depth() == CV_16F && m.channels() == 1 && m.rows == h) {
        // A 2-D array: wrong number of dimensions.
        ThrowInputError(path, ": expected ", feature_expect);
      }
      frame->features = CheckNpyImage(m, path, CV_16F, kFeatureDim, mv, feature_expect);
    } else {
      CheckNpyHeaderOnly(path, "<f2", {h, w, kFeatureDim}, feature_expect);
    }
  }
  if (mv.present.flow) {
    for (int g : manifest.flow_gaps) {
      for (int sign : {+1, -1}) {
        const int other = t + sign * g;
        if (other < 0 || other >= n) continue;
        const std::string folder =
            vdir + "/flow/" + (sign > 0 ? "fw_" : "bw_") + std::to_string(g) + "/";
        FlowField ff;
        ff.gap = sign * g;
        if (manifest.flow_encoding == FlowEncoding::kKittiPng16) {
          const std::string path = folder + png;
          if (!options.load_flow) {
            CheckPngFile(path, CV_16U, 3, w, h);
            continue;
          }
          const cv::Mat encoded = DecodePngStrict(ReadFileBytes(path), path, CV_16U, 3, w, h);
          cv::Mat flow32;
          DecodeFlowKitti(encoded, path, &flow32, &ff.valid);
          flow32.convertTo(ff.flow, CV_16F);
        } else {
          const std::string path = folder + npy;
          const char* expect = "a float16 array of shape (height, width, 3): u, v, valid";
          if (!options.load_flow) {
            CheckNpyHeaderOnly(path, "<f2", {h, w, 3}, expect);
            continue;
          }
          const cv::Mat m = CheckNpyImage(ReadNpy(path), path, CV_16F, 3, mv, expect);
          cv::Mat m32;
          m.convertTo(m32, CV_32F);
          std::vector<cv::Mat> ch;
          cv::split(m32, ch);
          for (int r = 0; r < h; ++r) {
            const float* v = ch[2].ptr<float>(r);
            for (int c = 0; c < w; ++c) {
              if (v[c] != 0.0f && v[c] != 1.0f) {
                ThrowInputError(path, ": valid channel must be 0 or 1, found ", v[c], " at (x=", c,
                                ", y=", r, ")");
              }
            }
          }
          ch[2].convertTo(ff.valid, CV_8U, 255.0);
          cv::Mat uv;
          cv::merge(std::vector<cv::Mat>{ch[0], ch[1]}, uv);
          uv.convertTo(ff.flow, CV_16F);
        }
        frame->flows.push_back(std::move(ff));
      }
    }
  }
  if (mv.present.depth) {
    if (manifest.depth_encoding == DepthEncoding::kPng16) {
      const std::string path = vdir + "/depth/" + png;
      if (options.load_depth) {
        const cv::Mat d16 = DecodePngStrict(ReadFileBytes(path), path, CV_16U, 1, w, h);
        d16.convertTo(frame->depth, CV_32F, manifest.depth_unit);
      } else {
        CheckPngFile(path, CV_16U, 1, w, h);
      }
    } else {
      const std::string path = vdir + "/depth/" + npy;
      const char* expect = "a float32 ('<f4') array of shape (height, width), finite, >= 0";
      if (options.load_depth) {
        frame->depth = CheckNpyImage(ReadNpy(path), path, CV_32F, 1, mv, expect);
        double lo = 0;
        cv::minMaxLoc(frame->depth, &lo);
        if (lo < 0) ThrowInputError(path, ": negative depth, expected ", expect);
      } else {
        CheckNpyHeaderOnly(path, "<f4", {h, w}, expect);
      }
    }
  }
  if (mv.present.mask_gt) {
    const std::string path = vdir + "/mask_gt/" + png;
    if (options.load_mask_gt) {
      frame->mask_gt = DecodePngStrict(ReadFileBytes(path), path, CV_8U, 1, w, h);
      for (int r = 0; r < h; ++r) {
        const unsigned char* m = frame->mask_gt.ptr<unsigned char>(r);
        for (int c = 0; c < w; ++c) {
          if (m[c] != kMaskObject && m[c] != kMaskBackground && m[c] != kMaskIgnore) {
            ThrowInputError(path, ": mask value ", int(m[c]), " at (x=", c, ", y=", r,
                            "), expected 0 (background), 128 (ignore) or 255 (object)");
          }
        }
      }
    } else {
      CheckPngFile(path, CV_8U, 1, w, h);
    }
  }
  if (mv.present.gt_mesh) {
    const std::string path = vdir + "/gt_mesh/" + FrameFileName(t, "ply");
    CheckRegularFile(path);
    std::ifstream in(path, std::ios::binary);
    char magic[4] = {0, 0, 0, 0};
    in.read(magic, 4);
    if (!in || std::string(magic, 4) != "ply\n") {
      ThrowInputError(path, ": not a PLY file (expected it to start with 'ply')");
    }
    frame->gt_mesh_path = path;
  }
}

}  // namespace

Dataset LoadDataset(const std::string& dir, const LoadOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) ThrowInputError(dir, ": not a folder (expected a dataset)");
  const std::string root = fs::absolute(dir, ec).lexically_normal().string();
  internal::RecoverInterruptedAdd(root);
  const internal::Manifest manifest = internal::ReadManifest(root + "/" + internal::kManifestName);

  // 1. Structure: exactly the expected files and folders (cheap, serial).
  std::set<std::string> video_dirs;
  for (const auto& mv : manifest.videos) video_dirs.insert(mv.name);
  CheckListing(root, {internal::kManifestName}, video_dirs, "dataset root");
  Dataset dataset;
  dataset.root = root;
  dataset.flow_gaps = manifest.flow_gaps;
  struct Job {
    int video;
    int frame;
  };
  std::vector<Job> jobs;
  for (int v = 0; v < static_cast<int>(manifest.videos.size()); ++v) {
    const internal::ManifestVideo& mv = manifest.videos[v];
    const std::string vdir = root + "/" + mv.name;
    const std::string what = "video '" + mv.name + "', " + std::to_string(mv.frames) + " frames";
    std::set<std::string> files = {internal::kPosesInitName};
    std::set<std::string> dirs = {"rgb", "mask"};
    if (mv.present.root_poses_gt) files.insert(internal::kPosesGtName);
    if (mv.present.flow) dirs.insert("flow");
    if (mv.present.features) dirs.insert("features");
    if (mv.present.depth) dirs.insert("depth");
    if (mv.present.gt_mesh) dirs.insert("gt_mesh");
    if (mv.present.mask_gt) dirs.insert("mask_gt");
    CheckListing(vdir, files, dirs, what);
    CheckListing(vdir + "/rgb", FrameFiles(0, mv.frames, "png"), {}, what, mv.frames);
    CheckListing(vdir + "/mask", FrameFiles(0, mv.frames, "png"), {}, what, mv.frames);
    if (mv.present.features) {
      CheckListing(vdir + "/features", FrameFiles(0, mv.frames, "npy"), {}, what, mv.frames);
    }
    const std::string depth_ext = manifest.depth_encoding == DepthEncoding::kPng16 ? "png" : "npy";
    if (mv.present.depth) {
      CheckListing(vdir + "/depth", FrameFiles(0, mv.frames, depth_ext), {}, what, mv.frames);
    }
    if (mv.present.gt_mesh) {
      CheckListing(vdir + "/gt_mesh", FrameFiles(0, mv.frames, "ply"), {}, what, mv.frames);
    }
    if (mv.present.mask_gt) {
      CheckListing(vdir + "/mask_gt", FrameFiles(0, mv.frames, "png"), {}, what, mv.frames);
    }
    if (mv.present.flow) {
      const std::string flow_ext =
          manifest.flow_encoding == FlowEncoding::kKittiPng16 ? "png" : "npy";
      std::set<std::string> gap_dirs;
      for (int g : manifest.flow_gaps) {
        gap_dirs.insert("fw_" + std::to_string(g));
        gap_dirs.insert("bw_" + std::to_string(g));
      }
      CheckListing(vdir + "/flow", {}, gap_dirs, what + ", flow gaps from the manifest");
      for (int g : manifest.flow_gaps) {
        const int pairs = std::max(0, mv.frames - g);
        const std::string gwhat = what + ", flow with gap " + std::to_string(g);
        CheckListing(vdir + "/flow/fw_" + std::to_string(g), FrameFiles(0, pairs, flow_ext), {},
                     gwhat + ": frames 0.." + std::to_string(mv.frames - 1 - g), pairs);
        CheckListing(vdir + "/flow/bw_" + std::to_string(g),
                     FrameFiles(std::min(g, mv.frames), mv.frames, flow_ext), {},
                     gwhat + ": frames " + std::to_string(g) + ".." + std::to_string(mv.frames - 1),
                     pairs);
      }
    }
    Video video;
    video.name = mv.name;
    video.camera.width = mv.width;
    video.camera.height = mv.height;
    video.camera.intrinsics = mv.intrinsics;
    video.intrinsics_gt = mv.intrinsics_gt;
    video.present = mv.present;
    const std::vector<Pose> init = ReadPoseFile(vdir + "/" + internal::kPosesInitName, mv.frames);
    std::vector<Pose> gt;
    if (mv.present.root_poses_gt) gt = ReadPoseFile(vdir + "/" + internal::kPosesGtName, mv.frames);
    video.frames.resize(mv.frames);
    for (int t = 0; t < mv.frames; ++t) {
      Frame& f = video.frames[t];
      f.index = t;
      f.root_pose_init = init[t];
      if (mv.present.root_poses_gt) f.root_pose_gt = gt[t];
      jobs.push_back({v, t});
    }
    dataset.videos.push_back(std::move(video));
  }

  // 2. Frames, both cores. Each frame writes only its own Frame; the first
  // error in frame order is reported.
  std::vector<std::exception_ptr> errors(jobs.size());
  ParallelFor(static_cast<int>(jobs.size()), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const int v = jobs[i].video;
      try {
        LoadFrame(manifest, manifest.videos[v], root + "/" + manifest.videos[v].name, options,
                  &dataset.videos[v].frames[jobs[i].frame]);
      } catch (...) {
        errors[i] = std::current_exception();
        return;
      }
    }
  });
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  return dataset;
}

}  // namespace banmo
