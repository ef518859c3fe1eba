// banmo prepare on a sequence with known motion: a random texture moved by a
// known rotation + translation per frame, so the exact flow between any two
// frames is known. Measures the endpoint error (EPE) of the DIS flow and the
// accuracy of the forward-backward occlusion check.
#include "banmo/io/prepare.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "banmo/io/npy.h"
#include "banmo/util/error.h"
#include "test_dataset_util.h"

namespace banmo {
namespace {

using testing::TempDir;

constexpr int kWidth = 192;
constexpr int kHeight = 160;
constexpr int kFrames = 10;
constexpr int kTexture = 400;

// Frame t shows texture point p at x = R(0.015 t) (p - c_tex) + c_frame + t (1.2, -0.7),
// in pixel index coordinates (pixel centres at integers, as cv::warpAffine).
cv::Matx23d TextureToFrame(int t) {
  const double a = 0.015 * t;
  const double c = std::cos(a), s = std::sin(a);
  const double ct = kTexture / 2.0;
  const double cx = kWidth / 2.0 + 1.2 * t;
  const double cy = kHeight / 2.0 - 0.7 * t;
  return cv::Matx23d(c, -s, cx - (c * ct - s * ct), s, c, cy - (s * ct + c * ct));
}

cv::Vec2d Apply(const cv::Matx23d& m, const cv::Vec2d& p) {
  return cv::Vec2d(m(0, 0) * p[0] + m(0, 1) * p[1] + m(0, 2),
                   m(1, 0) * p[0] + m(1, 1) * p[1] + m(1, 2));
}

cv::Mat MakeTexture() { return testing::SmoothRandomTexture(kTexture, kTexture, 12345); }

struct Sequence {
  std::string frames_dir;
  std::string masks_dir;
};

// Writes the frames and BANMo-format masks (disc of radius 40 px = 128,
// ring up to 48 px = 255 ignore) into `root`.
Sequence WriteSequence(const std::string& root) {
  Sequence s{root + "/frames", root + "/masks"};
  std::filesystem::create_directories(s.frames_dir);
  std::filesystem::create_directories(s.masks_dir);
  const cv::Mat texture = MakeTexture();
  for (int t = 0; t < kFrames; ++t) {
    cv::Mat frame;
    cv::warpAffine(texture, frame, TextureToFrame(t), cv::Size(kWidth, kHeight), cv::INTER_CUBIC,
                   cv::BORDER_REFLECT);
    char name[32];
    std::snprintf(name, sizeof(name), "img_%03d.png", t);
    cv::imwrite(s.frames_dir + "/" + name, frame);  // colour order is irrelevant here
    cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
    cv::circle(mask, cv::Point(kWidth / 2, kHeight / 2), 48, cv::Scalar(255), cv::FILLED);
    cv::circle(mask, cv::Point(kWidth / 2, kHeight / 2), 40, cv::Scalar(128), cv::FILLED);
    cv::imwrite(s.masks_dir + "/" + name, mask);
  }
  return s;
}

TEST(Prepare, RootsOnMaskCentroids) {
  // Four frames of 40 x 30 px, fx = 50, fy = 60, principal point (20, 15):
  // a 4 x 2 px object at columns 4-7, rows 20-21 (centroid at pixel
  // position (6, 21) with pixel centres at +0.5), one 1 px object at
  // (30, 5) -> (30.5, 5.5), and two empty frames that take the nearest
  // frame's translation. The root origin lands
  // on the centroid's ray at the given depth; rotations are kept.
  Video video;
  video.camera.width = 40;
  video.camera.height = 30;
  video.camera.intrinsics = Eigen::Vector4d(50, 60, 20, 15);
  video.frames.resize(4);
  for (Frame& f : video.frames) {
    f.mask = cv::Mat(30, 40, CV_8UC1, cv::Scalar(kMaskBackground));
    f.root_pose_init = PoseIdentity();
  }
  video.frames[0].mask(cv::Rect(4, 20, 4, 2)).setTo(kMaskObject);
  video.frames[0].mask.at<unsigned char>(0, 0) = kMaskIgnore;  // not the object
  video.frames[3].mask.at<unsigned char>(5, 30) = kMaskObject;
  video.frames[3].root_pose_init[kPoseQw] = 0.0;
  video.frames[3].root_pose_init[kPoseQw + 1] = 1.0;
  PlaceRootsOnMaskCentroids(2.0, /*depth_from_size=*/false, &video);
  auto expect_on_ray = [&](int t, double u, double v) {
    const Pose& g = video.frames[t].root_pose_init;
    EXPECT_NEAR(g[kPoseT + 2], 2.0, 1e-12) << t;
    EXPECT_NEAR(50.0 * g[kPoseT] / g[kPoseT + 2] + 20.0, u, 1e-9) << t;
    EXPECT_NEAR(60.0 * g[kPoseT + 1] / g[kPoseT + 2] + 15.0, v, 1e-9) << t;
  };
  expect_on_ray(0, 6.0, 21.0);
  expect_on_ray(1, 6.0, 21.0);  // nearest: frame 0
  expect_on_ray(2, 30.5, 5.5);  // nearest: frame 3
  expect_on_ray(3, 30.5, 5.5);
  EXPECT_EQ(video.frames[3].root_pose_init[kPoseQw + 1], 1.0);
  EXPECT_EQ(video.frames[0].root_pose_init[kPoseQw], 1.0);
}

TEST(Prepare, RootDepthFromMaskSize) {
  // Five frames of 60 x 40 px, fx = fy = 50, principal point (30, 20), with
  // object squares of side 8, 4, 16, 8 and 1 px (areas 64, 16, 256, 64, 1;
  // median 64) and one empty frame. Depth = 2 sqrt(64 / area): 2, 4, 1, 2,
  // and 16 clamped to 2 x kMaxRootDepthRatio = 6; the empty frame takes its
  // nearest neighbour's translation. Each origin stays on its centroid's ray.
  Video video;
  video.camera.width = 60;
  video.camera.height = 40;
  video.camera.intrinsics = Eigen::Vector4d(50, 50, 30, 20);
  const int sides[] = {8, 4, 16, 8, 1, 0};
  video.frames.resize(6);
  for (int t = 0; t < 6; ++t) {
    Frame& f = video.frames[t];
    f.mask = cv::Mat(40, 60, CV_8UC1, cv::Scalar(kMaskBackground));
    if (sides[t] > 0) f.mask(cv::Rect(10 + t, 5 + t, sides[t], sides[t])).setTo(kMaskObject);
    f.root_pose_init = PoseIdentity();
  }
  PlaceRootsOnMaskCentroids(2.0, /*depth_from_size=*/true, &video);
  const double depths[] = {2.0, 4.0, 1.0, 2.0, 2.0 * kMaxRootDepthRatio};
  for (int t = 0; t < 5; ++t) {
    const Pose& g = video.frames[t].root_pose_init;
    EXPECT_NEAR(g[kPoseT + 2], depths[t], 1e-12) << t;
    const double u = 10 + t + sides[t] / 2.0, v = 5 + t + sides[t] / 2.0;
    EXPECT_NEAR(50.0 * g[kPoseT] / g[kPoseT + 2] + 30.0, u, 1e-9) << t;
    EXPECT_NEAR(50.0 * g[kPoseT + 1] / g[kPoseT + 2] + 20.0, v, 1e-9) << t;
  }
  EXPECT_EQ(video.frames[5].root_pose_init, video.frames[4].root_pose_init);

  // Off: every frame at the given depth.
  PlaceRootsOnMaskCentroids(2.0, /*depth_from_size=*/false, &video);
  for (int t = 0; t < 6; ++t) EXPECT_EQ(video.frames[t].root_pose_init[kPoseT + 2], 2.0) << t;
}

TEST(Prepare, DisFlowMatchesKnownMotion) {
  TempDir tmp;
  const Sequence seq = WriteSequence(tmp.path());
  PrepareOptions options;
  options.frames_dir = seq.frames_dir;
  options.masks_dir = seq.masks_dir;
  const Dataset d = PrepareDataset(options);

  ASSERT_EQ(d.videos.size(), 1u);
  const Video& v = d.videos[0];
  ASSERT_EQ(static_cast<int>(v.frames.size()), kFrames);
  EXPECT_EQ(v.camera.intrinsics, Eigen::Vector4d(192, 192, 96, 80));
  EXPECT_EQ(d.flow_gaps, (std::vector<int>{1, 2, 4, 8}));
  // BANMo mask format detected: 128 -> object, 255 -> ignore.
  EXPECT_EQ(v.frames[0].mask.at<unsigned char>(kHeight / 2, kWidth / 2), kMaskObject);
  EXPECT_EQ(v.frames[0].mask.at<unsigned char>(kHeight / 2, kWidth / 2 + 44), kMaskIgnore);
  EXPECT_EQ(v.frames[0].mask.at<unsigned char>(0, 0), kMaskBackground);
  EXPECT_EQ(v.frames[3].root_pose_init[kPoseT + 2], 3.0);
  EXPECT_EQ(v.frames[3].root_pose_init[kPoseQw], 1.0);

  for (int gap : {1, 2, 4, 8}) {
    for (int sign : {1, -1}) {
      double epe_sum = 0, epe_valid_sum = 0;
      long visible = 0, visible_marked_valid = 0, hidden = 0, hidden_marked_invalid = 0;
      for (int t = 0; t < kFrames; ++t) {
        const FlowField* ff = v.frames[t].FlowForGap(sign * gap);
        if (t + sign * gap < 0 || t + sign * gap >= kFrames) {
          EXPECT_EQ(ff, nullptr);
          continue;
        }
        ASSERT_NE(ff, nullptr);
        cv::Mat flow;
        ff->flow.convertTo(flow, CV_32F);
        cv::Matx23d to_texture;
        cv::invertAffineTransform(TextureToFrame(t), to_texture);
        const cv::Matx23d to_other = TextureToFrame(t + sign * gap);
        for (int y = 0; y < kHeight; ++y) {
          for (int x = 0; x < kWidth; ++x) {
            const cv::Vec2d target = Apply(to_other, Apply(to_texture, cv::Vec2d(x, y)));
            const bool inside = target[0] >= -0.5 && target[0] < kWidth - 0.5 &&
                                target[1] >= -0.5 && target[1] < kHeight - 0.5;
            const bool marked_valid = ff->valid.at<unsigned char>(y, x) != 0;
            if (!inside) {
              ++hidden;
              hidden_marked_invalid += marked_valid ? 0 : 1;
              continue;
            }
            const cv::Vec2f f = flow.at<cv::Vec2f>(y, x);
            const double epe = std::hypot(f[0] - (target[0] - x), f[1] - (target[1] - y));
            epe_sum += epe;
            ++visible;
            if (marked_valid) {
              epe_valid_sum += epe;
              ++visible_marked_valid;
            }
          }
        }
      }
      const double epe = epe_sum / visible;
      const double epe_valid = epe_valid_sum / std::max(1L, visible_marked_valid);
      const double recall = static_cast<double>(visible_marked_valid) / visible;
      const double occ_recall =
          hidden > 0 ? static_cast<double>(hidden_marked_invalid) / hidden : 1;
      std::printf(
          "gap %+d: EPE %.3f px over visible pixels, %.3f px over pixels marked valid; "
          "visible marked valid %.1f %%, out-of-view marked invalid %.1f %% (%ld px)\n",
          sign * gap, epe, epe_valid, 100 * recall, 100 * occ_recall, hidden);
      // Measured (DIS PRESET_MEDIUM, this texture and motion): EPE 0.05 px
      // at gap 1 growing to 0.18 px at gap 8 (motion up to ~20 px). The
      // bound is about twice that: it catches a broken pipeline (wrong
      // direction or sign, frame order, half-float storage, a lost pyramid
      // level would give >= 0.5 px) without failing on small numeric changes
      // across OpenCV versions.
      const double bound = 0.1 + 0.03 * gap;
      EXPECT_LT(epe, bound) << "gap " << sign * gap;
      EXPECT_LT(epe_valid, bound) << "gap " << sign * gap;
      // Measured >= 99.5 % and >= 98.5 %: no occlusion here besides leaving
      // the image, so the forward-backward check must agree almost always.
      EXPECT_GT(recall, 0.98) << "gap " << sign * gap;
      EXPECT_GT(occ_recall, 0.95) << "gap " << sign * gap;
    }
  }
}

// Small sequence for the input tests: 3 frames of 32 x 24.
std::string WriteTiny(const std::string& root, const std::vector<cv::Mat>& masks) {
  std::filesystem::create_directories(root + "/frames");
  std::filesystem::create_directories(root + "/masks");
  cv::RNG rng(1);
  for (std::size_t t = 0; t < masks.size(); ++t) {
    cv::Mat frame(24, 32, CV_8UC3);
    rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
    const std::string name = std::to_string(t) + ".png";
    cv::imwrite(root + "/frames/" + name, frame);
    if (!masks[t].empty()) cv::imwrite(root + "/masks/" + name, masks[t]);
  }
  return root;
}

cv::Mat Square(unsigned char background, unsigned char object) {
  cv::Mat m(24, 32, CV_8UC1, cv::Scalar(background));
  m(cv::Rect(8, 6, 10, 8)).setTo(object);
  return m;
}

PrepareOptions TinyOptions(const std::string& root) {
  PrepareOptions o;
  o.frames_dir = root + "/frames";
  o.masks_dir = root + "/masks";
  o.gaps = {1};
  return o;
}

void ExpectPrepareError(const PrepareOptions& o, const std::vector<std::string>& fragments) {
  try {
    PrepareDataset(o);
    FAIL() << "PrepareDataset accepted bad input";
  } catch (const InputError& e) {
    for (const std::string& f : fragments) {
      EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << e.what();
    }
  }
}

TEST(Prepare, BinaryMasks0255And01) {
  for (unsigned char one : {255, 1}) {
    TempDir tmp;
    const std::string root =
        WriteTiny(tmp.path(), {Square(0, one), Square(0, one), Square(0, one)});
    const Dataset d = PrepareDataset(TinyOptions(root));
    const cv::Mat& m = d.videos[0].frames[1].mask;
    EXPECT_EQ(m.at<unsigned char>(10, 10), kMaskObject);
    EXPECT_EQ(m.at<unsigned char>(0, 0), kMaskBackground);
    EXPECT_EQ(cv::countNonZero(m == kMaskObject), 80);
  }
}

TEST(Prepare, ForcedBinaryThresholdsAntialiasedMasks) {
  TempDir tmp;
  const std::string root = WriteTiny(tmp.path(), {Square(0, 200), Square(3, 255), Square(0, 255)});
  PrepareOptions o = TinyOptions(root);
  ExpectPrepareError(o, {"mask value", "--mask-format binary"});  // auto cannot tell
  o.mask_format = MaskFormat::kBinary;
  const Dataset d = PrepareDataset(o);
  EXPECT_EQ(cv::countNonZero(d.videos[0].frames[0].mask == kMaskObject), 80);
  EXPECT_EQ(cv::countNonZero(d.videos[0].frames[1].mask == kMaskObject), 80);
}

TEST(Prepare, PosesFileAndIntrinsics) {
  TempDir tmp;
  const std::string root = WriteTiny(tmp.path(), {Square(0, 255), Square(0, 255), Square(0, 255)});
  PrepareOptions o = TinyOptions(root);
  std::vector<Pose> poses(3, PoseIdentity());
  poses[2][kPoseT] = 0.5;
  WritePoseFile(tmp.path() + "/poses.txt", poses);
  o.poses_path = tmp.path() + "/poses.txt";
  o.intrinsics = Eigen::Vector4d(40, 41, 16, 12);
  const Dataset d = PrepareDataset(o);
  EXPECT_EQ(d.videos[0].frames[2].root_pose_init, poses[2]);
  EXPECT_EQ(d.videos[0].camera.intrinsics, *o.intrinsics);
  poses.pop_back();
  WritePoseFile(tmp.path() + "/poses.txt", poses);
  ExpectPrepareError(o, {"poses.txt", "expected 3 pose lines"});
}

TEST(Prepare, RejectsMissingAndMismatchedMasks) {
  TempDir tmp;
  const std::string root = WriteTiny(tmp.path(), {Square(0, 255), cv::Mat(), Square(0, 255)});
  ExpectPrepareError(TinyOptions(root), {"masks", "no mask for frame '1'"});
  cv::imwrite(root + "/masks/1.png", cv::Mat(20, 32, CV_8UC1, cv::Scalar(0)));
  ExpectPrepareError(TinyOptions(root), {"masks/1.png", "32x20", "32x24"});
  PrepareOptions o = TinyOptions(root);
  o.frames_dir = tmp.path() + "/nothing";
  ExpectPrepareError(o, {"nothing", "not a folder"});
}

// Features 0.5 everywhere for the three frames of WriteTiny.
void WriteFeatures(const std::string& root) {
  std::filesystem::create_directories(root + "/features");
  for (int t = 0; t < 3; ++t) {
    WriteNpy(root + "/features/" + std::to_string(t) + ".npy",
             cv::Mat(24, 32 * kFeatureDim, CV_32FC1, cv::Scalar(0.5)).reshape(kFeatureDim));
  }
}

TEST(Prepare, FeaturesAreZeroOutsideTheMask) {
  TempDir tmp;
  const std::string root = WriteTiny(tmp.path(), {Square(0, 255), Square(0, 255), Square(0, 255)});
  WriteFeatures(root);
  PrepareOptions o = TinyOptions(root);
  o.features_dir = root + "/features";
  const Dataset d = PrepareDataset(o);
  const cv::Mat& f = d.videos[0].frames[0].features;
  ASSERT_EQ(f.type(), CV_16FC(kFeatureDim));
  cv::Mat f32;
  f.convertTo(f32, CV_32F);
  using FeatureVec = cv::Vec<float, kFeatureDim>;
  EXPECT_EQ(f32.at<FeatureVec>(10, 10)[3], 0.5f);
  EXPECT_EQ(f32.at<FeatureVec>(0, 0)[3], 0.0f);
  WriteNpy(root + "/features/2.npy", cv::Mat(24, 32, CV_32FC(3), cv::Scalar::all(0.5)));
  ExpectPrepareError(o, {"features/2.npy", "(24, 32, 16)"});
}

// --max-size: 32 x 24 frames scaled to 16 x 12. The square (x 8-17,
// y 6-13) covers the output pixels x 4-8, y 3-6 (at least half of each);
// intrinsics and features scale with the frames; smaller frames stay.
TEST(Prepare, MaxSizeScalesFramesMasksIntrinsicsAndFeatures) {
  TempDir tmp;
  const std::string root = WriteTiny(tmp.path(), {Square(0, 255), Square(0, 255), Square(0, 255)});
  WriteFeatures(root);
  PrepareOptions o = TinyOptions(root);
  o.features_dir = root + "/features";
  o.intrinsics = Eigen::Vector4d(40, 41, 16, 12);
  o.max_size = 16;
  const Dataset d = PrepareDataset(o);
  const Video& v = d.videos[0];
  EXPECT_EQ(v.camera.width, 16);
  EXPECT_EQ(v.camera.height, 12);
  EXPECT_EQ(v.camera.intrinsics, Eigen::Vector4d(20, 20.5, 8, 6));
  const Frame& f = v.frames[1];
  ASSERT_EQ(f.rgb.size(), cv::Size(16, 12));
  ASSERT_EQ(f.mask.size(), cv::Size(16, 12));
  EXPECT_EQ(cv::countNonZero(f.mask == kMaskObject), 5 * 4);
  EXPECT_EQ(f.mask.at<unsigned char>(3, 4), kMaskObject);
  EXPECT_EQ(f.mask.at<unsigned char>(2, 4), kMaskBackground);
  ASSERT_EQ(f.features.size(), cv::Size(16, 12));
  cv::Mat f32;
  f.features.convertTo(f32, CV_32F);
  using FeatureVec = cv::Vec<float, kFeatureDim>;
  EXPECT_EQ(f32.at<FeatureVec>(4, 5)[7], 0.5f);
  EXPECT_EQ(f32.at<FeatureVec>(0, 0)[7], 0.0f);
  ASSERT_FALSE(f.flows.empty());
  EXPECT_EQ(f.flows[0].flow.size(), cv::Size(16, 12));
  // Frames already within the size are kept as they are.
  o.max_size = 32;
  EXPECT_EQ(PrepareDataset(o).videos[0].camera.width, 32);
  o.max_size = 8;
  ExpectPrepareError(o, {"--max-size", "16..16384", "8"});
}

TEST(Prepare, VideoFileInput) {
  TempDir tmp;
  const std::string video = tmp.path() + "/clip.avi";
  {
    // Motion-JPEG in AVI: OpenCV's built-in writer, no external codec needed.
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10,
                           cv::Size(64, 48));
    ASSERT_TRUE(writer.isOpened());
    cv::RNG rng(4);
    for (int t = 0; t < 5; ++t) {
      cv::Mat frame(48, 64, CV_8UC3);
      rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
      writer.write(frame);
    }
  }
  std::filesystem::create_directories(tmp.path() + "/masks");
  for (int t = 0; t < 6; ++t) {  // one more mask than frames: the extra one is unused
    cv::Mat mask(48, 64, CV_8UC1, cv::Scalar(0));
    mask(cv::Rect(10, 10, 20, 20)).setTo(255);
    cv::imwrite(tmp.path() + "/masks/m" + std::to_string(t) + ".png", mask);
  }
  PrepareOptions o;
  o.video_path = video;
  o.masks_dir = tmp.path() + "/masks";
  o.gaps = {1, 2};
  o.max_frames = 4;
  const Dataset d = PrepareDataset(o);
  ASSERT_EQ(d.videos[0].frames.size(), 4u);
  EXPECT_EQ(d.videos[0].camera.width, 64);
  EXPECT_EQ(d.videos[0].frames[3].flows.size(), 2u);  // bw 1 and bw 2
  WriteDataset(d, tmp.path() + "/ds");
  EXPECT_EQ(LoadDataset(tmp.path() + "/ds").NumFrames(), 4);
  o.video_path = tmp.path() + "/missing.avi";
  ExpectPrepareError(o, {"missing.avi", "cannot open", "no such file"});
  // A file that no backend reads names the file and what to do.
  std::ofstream(tmp.path() + "/garbage.avi") << "not a video";
  o.video_path = tmp.path() + "/garbage.avi";
  ExpectPrepareError(o, {"garbage.avi", "cannot open", "--frames"});
}

TEST(Prepare, FramesOfDifferentSizesNameTheFirstOffendingFile) {
  TempDir tmp;
  const std::string root =
      WriteTiny(tmp.path(), {Square(0, 255), Square(0, 255), Square(0, 255), Square(0, 255)});
  cv::imwrite(root + "/frames/2.png", cv::Mat(20, 30, CV_8UC3, cv::Scalar::all(9)));
  cv::imwrite(root + "/frames/3.png", cv::Mat(20, 30, CV_8UC3, cv::Scalar::all(9)));
  ExpectPrepareError(TinyOptions(root), {"frames/2.png", "30x20", "frames/0.png", "32x24"});
}

TEST(Prepare, FewerThanTwoUsableFramesIsAnError) {
  TempDir tmp;
  const cv::Mat empty(24, 32, CV_8UC1, cv::Scalar(0));
  const std::string root = WriteTiny(tmp.path(), {empty, Square(0, 255), empty});
  ExpectPrepareError(TinyOptions(root), {"frames", "only 1 usable frame(s) of 3", "at least 2"});
  PrepareOptions o = TinyOptions(root);
  o.max_frames = 1;  // one frame in all
  ExpectPrepareError(o, {"only 0 usable frame(s) of 1"});
}

TEST(Prepare, MasksOfAnotherSizeAreRefusedOrResizedOnRequest) {
  TempDir tmp;
  const std::string root = WriteTiny(tmp.path(), {Square(0, 255), Square(0, 255), Square(0, 255)});
  for (int t = 0; t < 3; ++t) {
    cv::Mat big;
    cv::resize(Square(0, 255), big, cv::Size(64, 48), 0, 0, cv::INTER_NEAREST);
    cv::imwrite(root + "/masks/" + std::to_string(t) + ".png", big);
  }
  PrepareOptions o = TinyOptions(root);
  ExpectPrepareError(o,
                     {"masks/0.png", "mask is 64x48", "frames/0.png", "32x24", "--resize-masks"});
  o.resize_masks = true;
  const Dataset d = PrepareDataset(o);
  EXPECT_EQ(cv::countNonZero(d.videos[0].frames[1].mask == kMaskObject), 80);
}

// Two prepared videos in one dataset: AddVideosToDataset.
Dataset TinyVideo(const std::string& root, const std::string& name) {
  WriteTiny(root, {Square(0, 255), Square(0, 255), Square(0, 255)});
  PrepareOptions o = TinyOptions(root);
  o.video_name = name;
  return PrepareDataset(o);
}

TEST(AddVideos, AddsWithoutTouchingTheExistingVideos) {
  TempDir tmp;
  const std::string ds = tmp.path() + "/ds";
  WriteDataset(TinyVideo(tmp.path() + "/a", "video_000"), ds);
  const auto before = std::filesystem::last_write_time(ds + "/video_000/rgb/00000.png");
  EXPECT_EQ(ReadDatasetInfo(ds).video_names, std::vector<std::string>{"video_000"});
  EXPECT_EQ(NextVideoName(ReadDatasetInfo(ds).video_names), "video_001");
  AddVideosToDataset(TinyVideo(tmp.path() + "/b", "video_001"), ds);
  AddVideosToDataset(TinyVideo(tmp.path() + "/c", "cat_walk"), ds + "/");  // trailing slash
  const Dataset d = LoadDataset(ds);
  ASSERT_EQ(d.videos.size(), 3u);
  EXPECT_EQ(d.videos[1].name, "video_001");
  EXPECT_EQ(d.videos[2].name, "cat_walk");
  EXPECT_EQ(d.NumFrames(), 9);
  EXPECT_EQ(std::filesystem::last_write_time(ds + "/video_000/rgb/00000.png"), before);
  EXPECT_EQ(NextVideoName({"video_000", "video_001", "video_003"}), "video_002");
  // Nothing left beside the dataset.
  for (const auto& e : std::filesystem::directory_iterator(tmp.path())) {
    EXPECT_EQ(e.path().filename().string().find(".add-"), std::string::npos) << e.path();
  }
}

TEST(AddVideos, NameClashAndOtherGapsAreErrors) {
  TempDir tmp;
  const std::string ds = tmp.path() + "/ds";
  WriteDataset(TinyVideo(tmp.path() + "/a", "video_000"), ds);
  try {
    AddVideosToDataset(TinyVideo(tmp.path() + "/b", "video_000"), ds);
    FAIL() << "accepted a clashing name";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("already has a video named 'video_000'"),
              std::string::npos)
        << e.what();
  }
  Dataset other = TinyVideo(tmp.path() + "/c", "video_001");
  other.flow_gaps = {1, 2};
  try {
    AddVideosToDataset(other, ds);
    FAIL() << "accepted other gaps";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("flow gaps are [1], the added video has [1,2]"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(AddVideosToDataset(other, tmp.path() + "/missing"), InputError);
  EXPECT_EQ(LoadDataset(ds).videos.size(), 1u);
}

TEST(AddVideos, FailureHalfWayLeavesTheDatasetIntact) {
  TempDir tmp;
  const std::string ds = tmp.path() + "/ds";
  WriteDataset(TinyVideo(tmp.path() + "/a", "video_000"), ds);
  const std::string manifest = testing::ReadText(ds + "/manifest.yaml");
  Dataset bad = TinyVideo(tmp.path() + "/b", "video_001");
  // A mask value WriteDataset refuses only when it reaches the last frame.
  bad.videos[0].frames[2].mask.at<unsigned char>(0, 0) = 7;
  try {
    AddVideosToDataset(bad, ds);
    FAIL() << "accepted a bad mask";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mask value 7"), std::string::npos) << e.what();
  }
  EXPECT_EQ(testing::ReadText(ds + "/manifest.yaml"), manifest);
  EXPECT_FALSE(std::filesystem::exists(ds + "/video_001"));
  EXPECT_EQ(LoadDataset(ds).videos.size(), 1u);
  for (const auto& e : std::filesystem::directory_iterator(tmp.path())) {
    EXPECT_EQ(e.path().filename().string().find("ds."), std::string::npos) << e.path();
  }
}

}  // namespace
}  // namespace banmo
