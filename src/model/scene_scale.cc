#include "banmo/model/scene_scale.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace banmo {
namespace {

// p-th percentile (p in [0, 1]) of a non-empty sample, linear interpolation
// between order statistics (numpy.percentile's default).
double Percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  const double rank = p * static_cast<double>(values.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(rank));
  const size_t hi = std::min(lo + 1, values.size() - 1);
  return values[lo] + (rank - static_cast<double>(lo)) * (values[hi] - values[lo]);
}

// The object pixels (kMaskObject) of a mask: their count, bounding box
// (inclusive pixel indices) and the sums of their pixel centres.
struct ObjectPixels {
  long count = 0;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
  double sx = 0, sy = 0;
};
ObjectPixels FindObjectPixels(const cv::Mat& mask) {
  ObjectPixels p;
  p.x0 = mask.cols;
  p.y0 = mask.rows;
  for (int y = 0; y < mask.rows; ++y) {
    const unsigned char* row = mask.ptr<unsigned char>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (row[x] != kMaskObject) continue;
      p.x0 = std::min(p.x0, x);
      p.x1 = std::max(p.x1, x);
      p.y0 = std::min(p.y0, y);
      p.y1 = std::max(p.y1, y);
      p.sx += x + 0.5;
      p.sy += y + 0.5;
      ++p.count;
    }
  }
  return p;
}

}  // namespace

SceneScaleEstimate EstimateSceneScale(const Dataset& dataset, const Eigen::Vector3d& centre) {
  std::vector<double> inside, border;
  for (const Video& video : dataset.videos) {
    const Eigen::Vector4d& k = video.camera.intrinsics;
    for (const Frame& frame : video.frames) {
      const double z = (IsometryFromPose(frame.root_pose_init.data()) * centre).z();
      if (frame.skip || frame.mask.empty() || !(z > 0) || !std::isfinite(z)) continue;
      const ObjectPixels p = FindObjectPixels(frame.mask);
      if (p.count == 0) continue;  // no object pixel
      const double w = (p.x1 - p.x0 + 1) / k[0], h = (p.y1 - p.y0 + 1) / k[1];
      const double size = 0.5 * z * std::sqrt(w * w + h * h);
      if (!std::isfinite(size)) continue;
      const bool touches =
          p.x0 == 0 || p.y0 == 0 || p.x1 == frame.mask.cols - 1 || p.y1 == frame.mask.rows - 1;
      (touches ? border : inside).push_back(size);
    }
  }
  SceneScaleEstimate out;
  out.frames_border = static_cast<int>(border.size());
  if (inside.empty()) {
    out.border_used = !border.empty();
    inside.swap(border);
  }
  out.frames_used = static_cast<int>(inside.size());
  if (inside.empty()) return out;  // nothing to measure: s = 1
  out.estimate = Percentile(inside, 0.9);
  if (out.estimate > 0 && std::isfinite(out.estimate)) {
    const long exponent = std::clamp(std::lround(std::log2(out.estimate)), -1000L, 1000L);
    out.scale = std::ldexp(1.0, static_cast<int>(exponent));
  }
  return out;
}

ObjectCentreEstimate EstimateObjectCentre(const Dataset& dataset) {
  // Camera centres o_f and unit rays d_f through the mask centroids, both in
  // the root frame.
  std::vector<Eigen::Vector3d> origins, directions;
  for (const Video& video : dataset.videos) {
    const Eigen::Vector4d& k = video.camera.intrinsics;
    for (const Frame& frame : video.frames) {
      if (frame.skip || frame.mask.empty()) continue;
      const ObjectPixels p = FindObjectPixels(frame.mask);
      if (p.count == 0) continue;
      const Eigen::Isometry3d camera_from_root = IsometryFromPose(frame.root_pose_init.data());
      const Eigen::Matrix3d root_from_camera = camera_from_root.linear().transpose();
      const Eigen::Vector3d o = -root_from_camera * camera_from_root.translation();
      const Eigen::Vector3d d =
          (root_from_camera *
           Eigen::Vector3d((p.sx / p.count - k[2]) / k[0], (p.sy / p.count - k[3]) / k[1], 1.0))
              .normalized();
      if (!o.allFinite() || !d.allFinite()) continue;
      origins.push_back(o);
      directions.push_back(d);
    }
  }
  ObjectCentreEstimate out;
  out.frames_used = static_cast<int>(origins.size());
  if (origins.empty()) return out;
  const double n = out.frames_used;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double distance = 0.0;
  for (const Eigen::Vector3d& o : origins) {
    mean += o / n;
    distance += o.norm() / n;
  }
  double spread = 0.0;
  for (const Eigen::Vector3d& o : origins) spread += (o - mean).squaredNorm() / n;
  out.baseline_ratio = distance > 0 ? std::sqrt(spread) / distance : 0.0;
  if (!(out.baseline_ratio >= kObjectCentreMinBaseline)) return out;
  // Normal equations of sum_f |(I - d_f d_f^T)(x - o_f)|^2 + prior n |x|^2.
  Eigen::Matrix3d a = kObjectCentrePrior * n * Eigen::Matrix3d::Identity();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (size_t f = 0; f < origins.size(); ++f) {
    const Eigen::Matrix3d p =
        Eigen::Matrix3d::Identity() - directions[f] * directions[f].transpose();
    a += p;
    b += p * origins[f];
  }
  const Eigen::Vector3d centre = a.ldlt().solve(b);
  if (!centre.allFinite()) return out;
  out.centre = centre;
  out.triangulated = true;
  return out;
}

double ResolveSceneScale(const Dataset& dataset, const ModelOptions& options,
                         const Eigen::Vector3d& centre) {
  return options.scene_scale ? *options.scene_scale : EstimateSceneScale(dataset, centre).scale;
}

}  // namespace banmo
