#include "banmo/registration/root_pose_error.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "banmo/geometry/nearest_rotation.h"
#include "banmo/geometry/se3.h"
#include "banmo/util/format.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

Eigen::Matrix3d Rotation(const Pose& p) { return IsometryFromPose(p.data()).linear(); }

// Through the quaternion (2 atan2(|v|, |w|)): accurate near 0, where
// acos((trace - 1) / 2) loses half the digits.
double AngleDeg(const Eigen::Matrix3d& r) {
  const Eigen::Quaterniond q(r);
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w())) * 180.0 / M_PI;
}

// A = argmin sum |R_gt A - R|_F^2 over frames [begin, end) = the SO(3)
// projection of sum R_gt^T R.
Eigen::Matrix3d Alignment(const std::vector<Eigen::Matrix3d>& gt,
                          const std::vector<Eigen::Matrix3d>& est, size_t begin, size_t end) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (size_t i = begin; i < end; ++i) sum += gt[i].transpose() * est[i];
  return NearestRotation(sum);
}

// Errors of `estimate(v, t)` against the ground truth of every usable frame.
template <class Estimate>
std::optional<RootPoseErrors> Errors(const Dataset& dataset, const Estimate& estimate) {
  std::vector<RootPoseErrors::FrameError> frames;
  std::vector<Eigen::Matrix3d> gt, est;
  for (size_t v = 0; v < dataset.videos.size(); ++v) {
    const Video& video = dataset.videos[v];
    for (size_t t = 0; t < video.frames.size(); ++t) {
      const Frame& f = video.frames[t];
      if (f.skip || !f.root_pose_gt) continue;
      frames.push_back({static_cast<int>(v), static_cast<int>(t), 0.0});
      gt.push_back(Rotation(*f.root_pose_gt));
      est.push_back(Rotation(estimate(static_cast<int>(v), static_cast<int>(t))));
    }
  }
  if (frames.empty()) return std::nullopt;
  RootPoseErrors out;
  out.alignment = Alignment(gt, est, 0, gt.size());
  out.alignment_deg = AngleDeg(out.alignment);
  std::vector<double> angles;
  for (size_t i = 0; i < gt.size(); ++i) {
    frames[i].rotation_deg = AngleDeg((gt[i] * out.alignment).transpose() * est[i]);
    angles.push_back(frames[i].rotation_deg);
  }
  // Each video aligned on its own.
  double video_total = 0.0;
  for (size_t begin = 0; begin < frames.size();) {
    size_t end = begin;
    while (end < frames.size() && frames[end].video == frames[begin].video) ++end;
    const Eigen::Matrix3d a = Alignment(gt, est, begin, end);
    for (size_t i = begin; i < end; ++i) {
      frames[i].video_rotation_deg = AngleDeg((gt[i] * a).transpose() * est[i]);
      video_total += frames[i].video_rotation_deg;
    }
    begin = end;
  }
  out.video_aligned_mean_deg = video_total / frames.size();
  out.frames = std::move(frames);
  double total = 0.0;
  for (double a : angles) total += a;
  out.mean_deg = total / angles.size();
  std::sort(angles.begin(), angles.end());
  const size_t rank = static_cast<size_t>(std::ceil(0.9 * angles.size()));
  out.p90_deg = angles[std::max<size_t>(rank, 1) - 1];
  out.max_deg = angles.back();
  return out;
}

void CheckSameFrames(const Model& model, const Dataset& dataset) {
  CHECK_EQ(model.num_videos(), static_cast<int>(dataset.videos.size()));
  for (int v = 0; v < model.num_videos(); ++v) {
    CHECK_EQ(model.video(v).frames.size(), dataset.videos[v].frames.size());
  }
}

}  // namespace

std::optional<RootPoseErrors> ComputeRootPoseErrors(const Model& model, const Dataset& dataset) {
  CheckSameFrames(model, dataset);
  return Errors(dataset, [&](int v, int t) { return model.RootPose(v, t); });
}

std::optional<RootPoseErrors> ComputeBodyPoseErrors(const Model& model, const Dataset& dataset) {
  CheckSameFrames(model, dataset);
  return Errors(dataset, [&](int v, int t) {
    const Pose root = model.RootPose(v, t);
    if (model.num_bones() == 0) return root;
    Pose mean = PoseIdentity();
    const Eigen::Vector4d q = MeanBoneRotation(model.num_bones(), model.frame(v, t).bones_t.data());
    std::copy(q.data(), q.data() + 4, mean.data() + kPoseQw);
    Pose body;
    PoseCompose(root.data(), mean.data(), body.data());
    return body;
  });
}

std::optional<RootPoseErrors> InitialRootPoseErrors(const Dataset& dataset) {
  return Errors(dataset, [&](int v, int t) { return dataset.videos[v].frames[t].root_pose_init; });
}

std::string RootPoseErrorsCsv(const RootPoseErrors& errors, const RootPoseErrors* body) {
  if (body != nullptr) CHECK_EQ(body->frames.size(), errors.frames.size());
  std::ostringstream out;
  out << "video,frame,rotation_error_deg" << (body != nullptr ? ",body_rotation_error_deg" : "")
      << "\n";
  for (size_t i = 0; i < errors.frames.size(); ++i) {
    const RootPoseErrors::FrameError& f = errors.frames[i];
    out << f.video << "," << f.frame << "," << FormatDouble(f.rotation_deg);
    if (body != nullptr) out << "," << FormatDouble(body->frames[i].rotation_deg);
    out << "\n";
  }
  return out.str();
}

}  // namespace banmo
