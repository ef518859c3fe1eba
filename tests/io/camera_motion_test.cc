// The camera's rotation from the background's flow (io/camera_motion.h):
// exact flow of a turning camera, an object that moves on its own, a view
// with no background, and prepare's DIS flow of a rendered pan.
#include "banmo/io/camera_motion.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "banmo/io/prepare.h"
#include "banmo/util/error.h"
#include "test_dataset_util.h"

namespace banmo {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;
const Eigen::Vector4d kIntrinsics(140, 140, 80, 60);

Eigen::Matrix3d K() {
  Eigen::Matrix3d k;
  k << kIntrinsics[0], 0, kIntrinsics[2], 0, kIntrinsics[1], kIntrinsics[3], 0, 0, 1;
  return k;
}

double DegreesBetween(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a * b.transpose()).angle() * 180.0 / M_PI;
}

// camera_t_from_camera_0: a pan of 1.5 deg a frame with some tilt and roll.
Eigen::Matrix3d TrueRotation(int t) {
  const double d = M_PI / 180.0;
  return (Eigen::AngleAxisd(1.5 * d * t, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(0.4 * d * t, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(0.2 * d * t, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

// A video whose gap-1 flow is the exact image motion of the turning camera
// (x' ~ K R K^-1 x) on the background and an unrelated motion (20, -9) px on
// the object, a 60 x 40 px box of the mask.
Video TurningCameraVideo(int frames) {
  Video video;
  video.camera.width = kWidth;
  video.camera.height = kHeight;
  video.camera.intrinsics = kIntrinsics;
  video.frames.resize(frames);
  for (int t = 0; t < frames; ++t) {
    Frame& f = video.frames[t];
    f.index = t;
    f.mask = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(kMaskBackground));
    f.mask(cv::Rect(50, 40, 60, 40)).setTo(kMaskObject);
    f.root_pose_init = PoseIdentity();
    if (t + 1 == frames) continue;
    const Eigen::Matrix3d h =
        K() * TrueRotation(t + 1) * TrueRotation(t).transpose() * K().inverse();
    FlowField flow;
    flow.gap = 1;
    flow.flow = cv::Mat(kHeight, kWidth, CV_16FC2);
    flow.valid = cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(1));
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        const Eigen::Vector3d p(x + 0.5, y + 0.5, 1.0);
        Eigen::Vector2d d = (h * p).hnormalized() - p.head<2>();
        if (f.mask.at<unsigned char>(y, x) == kMaskObject) d = Eigen::Vector2d(20, -9);
        flow.flow.at<cv::Vec<cv::float16_t, 2>>(y, x) = {cv::float16_t(static_cast<float>(d[0])),
                                                         cv::float16_t(static_cast<float>(d[1]))};
      }
    }
    f.flows.push_back(flow);
  }
  return video;
}

// The exact flow of a camera that turns as TrueRotation and moves by
// (0.08, 0.01, 0.03) a frame in front of a background at depth 2 on the left
// half of the view and 6 on the right: parallax that no homography fits.
Video MovingCameraVideo(int frames) {
  Video video = TurningCameraVideo(frames);
  const Eigen::Vector3d step(0.08, 0.01, 0.03);
  for (int t = 0; t + 1 < frames; ++t) {
    const Eigen::Matrix3d r = TrueRotation(t + 1) * TrueRotation(t).transpose();
    FlowField& flow = video.frames[t].flows[0];
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        if (video.frames[t].mask.at<unsigned char>(y, x) == kMaskObject) continue;
        const Eigen::Vector3d p(x + 0.5, y + 0.5, 1.0);
        const double depth = x < kWidth / 2 ? 2.0 : 6.0;
        const Eigen::Vector3d moved = r * (depth * K().inverse() * p) + step;
        const Eigen::Vector2d d = (K() * moved).hnormalized() - p.head<2>();
        flow.flow.at<cv::Vec<cv::float16_t, 2>>(y, x) = {cv::float16_t(static_cast<float>(d[0])),
                                                         cv::float16_t(static_cast<float>(d[1]))};
      }
    }
  }
  return video;
}

TEST(CameraRotation, ExactFlowOfATurningCamera) {
  const Video video = TurningCameraVideo(8);
  const CameraRotations r = EstimateCameraRotations(video, CameraRotationOptions());
  ASSERT_EQ(r.camera_from_first.size(), 8u);
  EXPECT_EQ(r.FailedSteps(), 0);
  // Half-float flow (about 1/1000 px at a few pixels) limits the fit to
  // thousandths of a degree a step; chained over 7 steps.
  for (int t = 0; t < 8; ++t) {
    EXPECT_LT(DegreesBetween(r.camera_from_first[t], TrueRotation(t)), 0.01) << t;
  }
  EXPECT_NEAR(r.step_deg[3], DegreesBetween(TrueRotation(4), TrueRotation(3)), 0.01);
}

TEST(CameraRotation, ParallaxTakesTheEssentialMatrix) {
  const Video video = MovingCameraVideo(6);
  const CameraRotations r = EstimateCameraRotations(video, CameraRotationOptions());
  EXPECT_EQ(r.FailedSteps(), 0);
  EXPECT_EQ(r.EssentialSteps(), 5);
  // The essential matrix's rotation from exact flow (half floats): the
  // five-point solver and RANSAC's threshold leave a few thousandths of a
  // degree a step.
  for (int t = 0; t < 6; ++t) {
    EXPECT_LT(DegreesBetween(r.camera_from_first[t], TrueRotation(t)), 0.02 * t + 0.001) << t;
  }
  // The pure turn of ExactFlowOfATurningCamera takes the homography.
  EXPECT_EQ(
      EstimateCameraRotations(TurningCameraVideo(4), CameraRotationOptions()).EssentialSteps(), 0);
}

TEST(CameraRotation, RootsTurnWithTheCameraAndKeepTheirTranslation) {
  Video video = TurningCameraVideo(4);
  for (Frame& f : video.frames) f.root_pose_init[kPoseT + 2] = 3.0;
  RotateRootsWithCamera(EstimateCameraRotations(video, CameraRotationOptions()), &video);
  for (int t = 0; t < 4; ++t) {
    const Eigen::Isometry3d g = IsometryFromPose(video.frames[t].root_pose_init.data());
    EXPECT_LT(DegreesBetween(g.rotation(), TrueRotation(t)), 0.01) << t;
    EXPECT_EQ(g.translation(), Eigen::Vector3d(0, 0, 3)) << t;
  }
}

TEST(CameraRotation, NoBackgroundMeansNoTurn) {
  Video video = TurningCameraVideo(5);
  for (Frame& f : video.frames) f.mask.setTo(kMaskObject);
  const CameraRotations r = EstimateCameraRotations(video, CameraRotationOptions());
  EXPECT_EQ(r.FailedSteps(), 4);
  for (const Eigen::Matrix3d& m : r.camera_from_first) EXPECT_TRUE(m.isIdentity(0.0));

  // Without gap-1 flow: identity too.
  for (Frame& f : video.frames) f.flows.clear();
  EXPECT_EQ(EstimateCameraRotations(video, CameraRotationOptions()).FailedSteps(), 4);
}

TEST(CameraRotation, OptionsAreChecked) {
  CameraRotationOptions o;
  o.max_step_deg = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = CameraRotationOptions();
  o.min_inlier_fraction = 1.5;
  EXPECT_THROW(o.Check(), InputError);
  o = CameraRotationOptions();
  o.homography_preference = -0.1;
  EXPECT_THROW(o.Check(), InputError);
  o = CameraRotationOptions();
  o.max_points = 3;
  EXPECT_THROW(EstimateCameraRotations(TurningCameraVideo(2), o), InputError);
}

// Frames of a panning camera rendered from a texture on a distant plane
// (x' ~ K R_t K^-1 x of the first frame's texture), with a disc-shaped
// object that moves across the view on its own: `banmo prepare
// --roots-turn-with-camera` turns the roots with the camera from its own DIS
// flow.
TEST(CameraRotation, PrepareTurnsRootsWithAPanningCamera) {
  testing::TempDir tmp;
  const std::string frames_dir = tmp.path() + "/frames", masks_dir = tmp.path() + "/masks";
  std::filesystem::create_directories(frames_dir);
  std::filesystem::create_directories(masks_dir);
  // A texture wider than the view: the first frame's pixels are texture
  // pixels shifted by `pad`.
  const int pad = 80;
  const cv::Mat texture = testing::SmoothRandomTexture(kHeight + 2 * pad, kWidth + 2 * pad, 7);
  const int frames = 6;
  for (int t = 0; t < frames; ++t) {
    // Frame pixel x shows first-frame pixel K R_t^T K^-1 x (pixel centres
    // at integers for cv::warpPerspective, as in the flow's convention
    // shifted by a constant that cancels in H).
    Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
    shift(0, 2) = pad;
    shift(1, 2) = pad;
    const Eigen::Matrix3d frame_to_texture =
        shift * K() * TrueRotation(t).transpose() * K().inverse();
    cv::Mat m(3, 3, CV_64F);
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) m.at<double>(i, j) = frame_to_texture(i, j);
    }
    cv::Mat image;
    cv::warpPerspective(texture, image, m, cv::Size(kWidth, kHeight),
                        cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
    cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
    const cv::Point centre(50 + 8 * t, 60);
    cv::circle(image, centre, 18, cv::Scalar(40, 200, 90), cv::FILLED);
    cv::circle(mask, centre, 18, cv::Scalar(255), cv::FILLED);
    char name[32];
    std::snprintf(name, sizeof(name), "f%02d.png", t);
    cv::imwrite(frames_dir + "/" + name, image);
    cv::imwrite(masks_dir + "/" + name, mask);
  }
  PrepareOptions options;
  options.frames_dir = frames_dir;
  options.masks_dir = masks_dir;
  options.intrinsics = kIntrinsics;
  options.roots_turn_with_camera = true;
  Dataset d = PrepareDataset(options);
  ASSERT_EQ(d.videos.size(), 1u);
  // DIS flow (medium preset) of this texture is off by 0.1 px on average,
  // biased along the pan by 0.06-0.09 px (measured): about 0.04-0.07 deg a
  // step at fx = 140, and the chain adds them up.
  for (int t = 0; t < frames; ++t) {
    const Eigen::Isometry3d g = IsometryFromPose(d.videos[0].frames[t].root_pose_init.data());
    EXPECT_LT(DegreesBetween(g.rotation(), TrueRotation(t)), 0.1 * t + 0.01) << t;
  }
  EXPECT_GT(DegreesBetween(TrueRotation(frames - 1), Eigen::Matrix3d::Identity()), 7.0);

  // The default: identity rotations.
  options.roots_turn_with_camera = PrepareOptions().roots_turn_with_camera;
  d = PrepareDataset(options);
  for (const Frame& f : d.videos[0].frames) {
    EXPECT_EQ(f.root_pose_init[kPoseQw], 1.0);
  }
}

}  // namespace
}  // namespace banmo
