#include "banmo/io/camera_motion.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "banmo/geometry/se3.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

void CameraRotationOptions::Check() const {
  if (mask_margin_px < 0) {
    ThrowInputError("CameraRotationOptions::mask_margin_px = ", mask_margin_px, ", expected >= 0");
  }
  if (max_points < 8) {
    ThrowInputError("CameraRotationOptions::max_points = ", max_points, ", expected >= 8");
  }
  if (!(std::isfinite(ransac_threshold_px) && ransac_threshold_px > 0)) {
    ThrowInputError("CameraRotationOptions::ransac_threshold_px = ", ransac_threshold_px,
                    ", expected > 0");
  }
  if (min_inliers < 4) {
    ThrowInputError("CameraRotationOptions::min_inliers = ", min_inliers, ", expected >= 4");
  }
  if (!(min_inlier_fraction >= 0 && min_inlier_fraction <= 1)) {
    ThrowInputError("CameraRotationOptions::min_inlier_fraction = ", min_inlier_fraction,
                    ", expected in [0, 1]");
  }
  if (!(std::isfinite(max_step_deg) && max_step_deg > 0)) {
    ThrowInputError("CameraRotationOptions::max_step_deg = ", max_step_deg, ", expected > 0");
  }
  if (!(homography_preference >= 0 && homography_preference <= 1)) {
    ThrowInputError("CameraRotationOptions::homography_preference = ", homography_preference,
                    ", expected in [0, 1]");
  }
}

int CameraRotations::FailedSteps() const {
  return static_cast<int>(std::count(step_ok.begin(), step_ok.end(), false));
}

int CameraRotations::EssentialSteps() const {
  return static_cast<int>(std::count(step_essential.begin(), step_essential.end(), true));
}

namespace {

// Background pixels of `frame` with valid flow, on a grid thin enough to
// keep about `max_points` of them: (pixel centre, its flow target).
void BackgroundCorrespondences(const Frame& frame, const FlowField& flow,
                               const CameraRotationOptions& options, std::vector<cv::Point2f>* from,
                               std::vector<cv::Point2f>* to) {
  cv::Mat near_object = frame.mask != kMaskBackground;
  if (options.mask_margin_px > 0) {
    const int side = 2 * options.mask_margin_px + 1;
    cv::dilate(near_object, near_object,
               cv::getStructuringElement(cv::MORPH_RECT, cv::Size(side, side)));
  }
  const int candidates = cv::countNonZero((near_object == 0) & (flow.valid != 0));
  const int stride = std::max(
      1,
      static_cast<int>(std::ceil(std::sqrt(static_cast<double>(candidates) / options.max_points))));
  from->clear();
  to->clear();
  for (int y = 0; y < near_object.rows; y += stride) {
    const unsigned char* object_row = near_object.ptr<unsigned char>(y);
    const unsigned char* valid_row = flow.valid.ptr<unsigned char>(y);
    const cv::Vec<cv::float16_t, 2>* f = flow.flow.ptr<cv::Vec<cv::float16_t, 2>>(y);
    for (int x = 0; x < near_object.cols; x += stride) {
      if (object_row[x] != 0 || valid_row[x] == 0) continue;
      const cv::Point2f p(x + 0.5f, y + 0.5f);
      from->push_back(p);
      to->push_back(p + cv::Point2f(static_cast<float>(f[x][0]), static_cast<float>(f[x][1])));
    }
  }
}

Eigen::Matrix3d ToEigen(const cv::Mat& m) {
  Eigen::Matrix3d out;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out(i, j) = m.at<double>(i, j);
  }
  return out;
}

// Nearest rotation (Frobenius) to K^-1 H K, or false if H is degenerate.
bool RotationFromHomography(const cv::Mat& h, const cv::Mat& camera, Eigen::Matrix3d* r) {
  const Eigen::Matrix3d km = ToEigen(camera);
  const Eigen::Matrix3d m = km.inverse() * ToEigen(h) * km;
  // A singular H (all points on a line) has no rotation near it.
  if (!m.allFinite() || !(std::abs(m.determinant()) > 1e-12 * std::pow(m.norm(), 3))) return false;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  *r = svd.matrixU() * svd.matrixV().transpose();
  // A homography is defined up to scale, its sign included.
  if (r->determinant() < 0) *r = -*r;
  return true;
}

double Degrees(const Eigen::Matrix3d& r) { return Eigen::AngleAxisd(r).angle() * 180.0 / M_PI; }

// The camera's rotation over one step from background correspondences, or
// false if no model keeps enough inliers and turns by at most
// max_step_deg. The essential matrix's rotation is tried first where the
// homography fits markedly fewer pixels; a rotation it cannot give (a
// decomposition of an almost pure turn can pick the twisted pair, 180 deg
// away) falls back to the homography's. OpenCV's RANSAC draws from a fixed
// seed: the same input gives the same rotation.
bool StepRotation(const std::vector<cv::Point2f>& from, const std::vector<cv::Point2f>& to,
                  const Eigen::Vector4d& k, const CameraRotationOptions& options,
                  Eigen::Matrix3d* r, bool* essential) {
  const double needed = std::max<double>(
      options.min_inliers, options.min_inlier_fraction * static_cast<double>(from.size()));
  cv::Mat h_inliers, e_inliers;
  const cv::Mat h =
      cv::findHomography(from, to, cv::RANSAC, options.ransac_threshold_px, h_inliers);
  const int h_kept = h.empty() ? 0 : cv::countNonZero(h_inliers);
  const cv::Mat camera = (cv::Mat_<double>(3, 3) << k[0], 0, k[2], 0, k[1], k[3], 0, 0, 1);
  const cv::Mat e = cv::findEssentialMat(from, to, camera, cv::RANSAC, 0.999,
                                         options.ransac_threshold_px, e_inliers);
  // findEssentialMat stacks up to ten solutions; the first is the best.
  const int e_kept = e.rows >= 3 ? cv::countNonZero(e_inliers) : 0;
  *essential = false;
  if (e_kept >= needed && h_kept < options.homography_preference * e_kept) {
    cv::Mat rotation, translation;
    cv::recoverPose(e.rowRange(0, 3), from, to, camera, rotation, translation, e_inliers);
    *r = ToEigen(rotation);
    if (r->allFinite() && Degrees(*r) <= options.max_step_deg) {
      *essential = true;
      return true;
    }
  }
  return h_kept >= needed && RotationFromHomography(h, camera, r) &&
         Degrees(*r) <= options.max_step_deg;
}

}  // namespace

CameraRotations EstimateCameraRotations(const Video& video, const CameraRotationOptions& options) {
  options.Check();
  const int n = static_cast<int>(video.frames.size());
  CameraRotations out;
  out.camera_from_first.assign(n, Eigen::Matrix3d::Identity());
  out.step_deg.assign(std::max(0, n - 1), 0.0);
  out.step_ok.assign(std::max(0, n - 1), false);
  out.step_essential.assign(std::max(0, n - 1), false);
  std::vector<cv::Point2f> from, to;
  for (int t = 0; t + 1 < n; ++t) {
    Eigen::Matrix3d step = Eigen::Matrix3d::Identity();
    const FlowField* flow = video.frames[t].FlowForGap(1);
    if (flow != nullptr) {
      BackgroundCorrespondences(video.frames[t], *flow, options, &from, &to);
      Eigen::Matrix3d r;
      bool essential = false;
      if (static_cast<int>(from.size()) >= options.min_inliers &&
          StepRotation(from, to, video.camera.intrinsics, options, &r, &essential)) {
        step = r;
        out.step_deg[t] = Degrees(r);
        out.step_ok[t] = true;
        out.step_essential[t] = essential;
      }
    }
    out.camera_from_first[t + 1] = step * out.camera_from_first[t];
  }
  return out;
}

void RotateRootsWithCamera(const CameraRotations& rotations, Video* video) {
  CHECK_EQ(rotations.camera_from_first.size(), video->frames.size());
  for (size_t t = 0; t < video->frames.size(); ++t) {
    Pose& pose = video->frames[t].root_pose_init;
    const Eigen::Quaterniond q(rotations.camera_from_first[t]);
    pose[kPoseQw + 0] = q.w();
    pose[kPoseQw + 1] = q.x();
    pose[kPoseQw + 2] = q.y();
    pose[kPoseQw + 3] = q.z();
  }
}

}  // namespace banmo
