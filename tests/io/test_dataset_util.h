// Helpers shared by the io tests: a small, valid in-memory dataset and temp
// folders.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "banmo/io/dataset.h"

namespace banmo::testing {

// A fresh, empty temporary folder removed at destruction.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = (std::filesystem::temp_directory_path() /
             ("banmo_io_test_" + std::to_string(::getpid()) + "_" + std::to_string(rd())))
                .string();
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// Smooth random colour texture (CV_8UC3, rows x cols): uniform noise blurred
// at two scales (sigma 1.5 and 5 px, the coarse one weighted 2), stretched
// to 0-255. DIS flow tracks it well at every scale it works on.
inline cv::Mat SmoothRandomTexture(int rows, int cols, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat fine(rows, cols, CV_32FC3), coarse(rows, cols, CV_32FC3);
  rng.fill(fine, cv::RNG::UNIFORM, 0.0, 1.0);
  rng.fill(coarse, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::GaussianBlur(fine, fine, cv::Size(), 1.5);
  cv::GaussianBlur(coarse, coarse, cv::Size(), 5.0);
  cv::Mat sum = fine + 2.0 * coarse;
  cv::normalize(sum, sum, 0, 255, cv::NORM_MINMAX);
  cv::Mat out;
  sum.convertTo(out, CV_8UC3);
  return out;
}

// Two videos (w x h, `frames` frames each), flow gaps {1, 2}, random content
// with every data type present. Flow values lie in [-6, 6] px.
inline Dataset MakeSmallDataset(int w = 24, int h = 20, int frames = 5, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uni(-1.f, 1.f);
  Dataset d;
  d.flow_gaps = {1, 2};
  for (int v = 0; v < 2; ++v) {
    Video video;
    video.name = "video" + std::to_string(v);
    video.camera.width = w;
    video.camera.height = h;
    video.camera.intrinsics = Eigen::Vector4d(30.5 + v, 31.25, w / 2.0, h / 2.0 + 0.5);
    for (int t = 0; t < frames; ++t) {
      Frame f;
      f.index = t;
      f.rgb.create(h, w, CV_8UC3);
      cv::randu(f.rgb, 0, 256);
      f.mask = cv::Mat::zeros(h, w, CV_8UC1);
      f.mask(cv::Rect(w / 4, h / 4, w / 2, h / 2)).setTo(kMaskObject);
      f.mask(cv::Rect(0, 0, 3, 3)).setTo(kMaskIgnore);
      cv::Mat feat(h, w, CV_32FC(kFeatureDim));
      cv::randu(feat, -1.0, 1.0);
      feat.convertTo(f.features, CV_16F);
      for (int g : d.flow_gaps) {
        for (int s : {1, -1}) {
          if (t + s * g < 0 || t + s * g >= frames) continue;
          FlowField ff;
          ff.gap = s * g;
          cv::Mat fl(h, w, CV_32FC2);
          cv::randu(fl, -6.0, 6.0);
          fl.convertTo(ff.flow, CV_16F);
          ff.valid.create(h, w, CV_8UC1);
          cv::randu(ff.valid, 0, 2);
          ff.valid *= 255;
          f.flows.push_back(ff);
        }
      }
      f.depth.create(h, w, CV_32FC1);
      cv::randu(f.depth, 2.0, 4.0);
      f.depth.setTo(0, f.mask != kMaskObject);
      f.root_pose_init = PoseFromAngleAxis(Eigen::Vector3d(uni(rng), uni(rng), uni(rng)),
                                           Eigen::Vector3d(uni(rng), uni(rng), 3 + uni(rng)));
      f.root_pose_gt = PoseFromAngleAxis(Eigen::Vector3d(uni(rng), uni(rng), uni(rng)),
                                         Eigen::Vector3d(uni(rng), uni(rng), 3 + uni(rng)));
      video.frames.push_back(f);
    }
    d.videos.push_back(video);
  }
  return d;
}

// A tetrahedron per frame, for the gt_mesh folder.
inline std::vector<std::vector<TriangleMesh>> MakeGtMeshes(const Dataset& d) {
  std::vector<std::vector<TriangleMesh>> out(d.videos.size());
  for (std::size_t v = 0; v < d.videos.size(); ++v) {
    for (std::size_t t = 0; t < d.videos[v].frames.size(); ++t) {
      TriangleMesh m;
      m.vertices.resize(3, 4);
      m.vertices << 0, 1, 0, 0, 0, 0, 1, 0, 3, 3, 3, 3.0 + 0.1 * t;
      m.faces.resize(3, 4);
      m.faces << 0, 0, 0, 1, 2, 1, 3, 2, 1, 3, 2, 3;
      out[v].push_back(m);
    }
  }
  return out;
}

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

inline void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

// Every optional part loaded (depth included).
inline LoadOptions LoadAll() {
  LoadOptions o;
  o.load_depth = true;
  return o;
}

// MakeSmallDataset with its ground-truth meshes written to tmp/ds.
inline std::string WriteValid(const TempDir& tmp, const WriteOptions& options = {}) {
  const std::string dir = tmp.path() + "/ds";
  const Dataset d = MakeSmallDataset();
  const auto meshes = MakeGtMeshes(d);
  WriteDataset(d, dir, options, &meshes);
  return dir;
}

}  // namespace banmo::testing
