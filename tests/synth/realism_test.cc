// `--realism casual` (realism.h, docs/synth.md "Realism"): each effect on a
// constructed case, and the written dataset (mask_gt, intrinsics_gt, no
// features, identity rough poses).
#include "banmo/synth/realism.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <set>

#include "banmo/io/dataset.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"
#include "banmo/util/error.h"

namespace banmo::synth {
namespace {

SynthOptions CasualOptionsFor(int videos, int frames, int size) {
  SynthOptions o;
  o.num_videos = videos;
  o.frames_per_video = frames;
  o.image_size = size;
  o.flow_gaps = {1};
  o.seed = 11;
  o.realism = Realism::kCasual;
  return o;
}

const Rig& Quadruped() {
  static const Rig rig = LoadRig("quadruped");
  return rig;
}

// Pixels where a and b (same type) differ in any channel.
cv::Mat Differs(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  if (d.channels() > 1) {
    cv::Mat flat = d.reshape(1, d.rows * d.cols);
    cv::reduce(flat, flat, 1, cv::REDUCE_MAX);
    d = flat.reshape(1, a.rows);
  }
  return d > 0;
}

TEST(Realism, PerVideoDrawsStayInTheirRanges) {
  const CasualOptions o;
  double fmin = 10, fmax = 0, emin = 10, emax = 0;
  for (int v = 0; v < 400; ++v) {
    const CasualVideo c = DrawCasualVideo(o, 5, v);
    EXPECT_GE(c.focal_factor, 0.6);
    EXPECT_LE(c.focal_factor, 1.6);
    EXPECT_GE(c.exposure, o.exposure_min);
    EXPECT_LE(c.exposure, o.exposure_max);
    EXPECT_GE(c.ambient, o.ambient_min);
    EXPECT_LE(c.ambient, o.ambient_max);
    for (int k : {0, 2}) {
      EXPECT_GE(c.white_balance[k], 1 - o.white_balance);
      EXPECT_LE(c.white_balance[k], 1 + o.white_balance);
    }
    EXPECT_EQ(c.white_balance[1], 1.0);
    EXPECT_NEAR(c.light_world.norm(), 1.0, 1e-12);
    const double elevation = std::asin(c.light_world.y()) * 180 / M_PI;
    EXPECT_GE(elevation, o.light_elevation_min_deg - 1e-9);
    EXPECT_LE(elevation, o.light_elevation_max_deg + 1e-9);
    EXPECT_GE(c.noise_gain, o.noise_gain_min);
    EXPECT_LE(c.noise_gain, o.noise_gain_max);
    fmin = std::min(fmin, c.focal_factor);
    fmax = std::max(fmax, c.focal_factor);
    emin = std::min(emin, c.exposure);
    emax = std::max(emax, c.exposure);
  }
  // The draws cover their ranges.
  EXPECT_LT(fmin, 0.65);
  EXPECT_GT(fmax, 1.55);
  EXPECT_LT(emin, 0.78);
  EXPECT_GT(emax, 1.25);
  // Same seed and video: the same draws; another video: others.
  EXPECT_EQ(DrawCasualVideo(o, 5, 3).focal_factor, DrawCasualVideo(o, 5, 3).focal_factor);
  EXPECT_NE(DrawCasualVideo(o, 5, 3).focal_factor, DrawCasualVideo(o, 5, 4).focal_factor);
  EXPECT_NE(DrawCasualVideo(o, 6, 3).focal_factor, DrawCasualVideo(o, 5, 3).focal_factor);
}

TEST(Realism, FocalPerVideoIsGroundTruthOnly) {
  const SynthOptions o = CasualOptionsFor(6, 2, 48);
  const ScenePlan plan = PlanScene(Quadruped(), o);
  const SynthScene scene = RenderSyntheticScene(Quadruped(), o);
  std::set<double> focals;
  for (int v = 0; v < o.num_videos; ++v) {
    const double f = plan.cameras[v].intrinsics[0] / o.image_size;
    EXPECT_GE(f, 0.6);
    EXPECT_LE(f, 1.6);
    focals.insert(f);
    const Video& video = scene.dataset.videos[v];
    // The dataset holds the default assumption; the truth only as ground truth.
    EXPECT_EQ(video.camera.intrinsics, Eigen::Vector4d(48, 48, 24, 24));
    ASSERT_TRUE(video.intrinsics_gt.has_value());
    EXPECT_EQ(*video.intrinsics_gt, plan.cameras[v].intrinsics);
    // The camera distance follows the focal length (the object keeps its
    // size): distance / focal within the +-5 % distance jitter.
    const double ratio = plan.paths[v].distance / f / o.camera_distance;
    EXPECT_GT(ratio, 0.95 - 1e-9);
    EXPECT_LT(ratio, 1.05 + 1e-9);
    for (const Frame& frame : video.frames) {
      EXPECT_TRUE(frame.features.empty());
      EXPECT_EQ(frame.root_pose_init, (Pose() << 1, 0, 0, 0, 0, 0, 3).finished());
      ASSERT_TRUE(frame.root_pose_gt.has_value());
      EXPECT_GT((frame.root_pose_gt->head<4>() - frame.root_pose_init.head<4>()).norm(), 1e-3);
    }
  }
  EXPECT_EQ(focals.size(), 6u);
}

TEST(Realism, BackgroundUnderTheObjectIsNotUsed) {
  SynthOptions o = CasualOptionsFor(2, 3, 64);
  o.casual.blur_subframes = 1;
  o.casual.noise_read = 0;
  o.casual.noise_shot = 0;
  o.casual.jpeg_quality = 0;
  const SynthScene with = RenderSyntheticScene(Quadruped(), o);
  o.casual.background = false;
  const SynthScene without = RenderSyntheticScene(Quadruped(), o);
  int object = 0, background = 0, background_changed = 0;
  for (int v = 0; v < o.num_videos; ++v) {
    for (int f = 0; f < o.frames_per_video; ++f) {
      const Frame& a = with.dataset.videos[v].frames[f];
      const Frame& b = without.dataset.videos[v].frames[f];
      ASSERT_EQ(cv::countNonZero(Differs(a.mask_gt, b.mask_gt)), 0);
      const cv::Mat changed = Differs(a.rgb, b.rgb);
      for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
          if (a.mask_gt.at<unsigned char>(y, x) == kMaskObject) {
            ++object;
            ASSERT_EQ(changed.at<unsigned char>(y, x), 0) << "object pixel " << x << "," << y;
          } else {
            ++background;
            EXPECT_EQ(b.rgb.at<cv::Vec3b>(y, x), cv::Vec3b(0, 0, 0));
            background_changed += changed.at<unsigned char>(y, x) != 0;
          }
        }
      }
    }
  }
  EXPECT_GT(object, 1000);
  // The world is drawn nearly everywhere else (dark texels may round to 0).
  EXPECT_GT(background_changed, 0.95 * background);
}

// With the plain camera (focal 1), full ambient light, unit exposure and
// white balance and no blur, noise or JPEG, the object's pixels are the plain
// renderer's (its own colours x shade 1); only rounding may differ.
TEST(Realism, ObjectPixelsAreTheShadedObjectColour) {
  SynthOptions o = CasualOptionsFor(2, 3, 64);
  o.casual.focal_min = o.casual.focal_max = 1.0;
  o.casual.ambient_min = o.casual.ambient_max = 1.0;
  o.casual.exposure_min = o.casual.exposure_max = 1.0;
  o.casual.white_balance = 0;
  o.casual.blur_subframes = 1;
  o.casual.noise_read = o.casual.noise_shot = 0;
  o.casual.jpeg_quality = 0;
  const SynthScene casual = RenderSyntheticScene(Quadruped(), o);
  o.realism = Realism::kNone;
  o.ambient = 1.0;
  const SynthScene plain = RenderSyntheticScene(Quadruped(), o);
  int object = 0, equal = 0;
  for (int v = 0; v < 2; ++v) {
    for (int f = 0; f < 3; ++f) {
      const Frame& a = casual.dataset.videos[v].frames[f];
      const Frame& b = plain.dataset.videos[v].frames[f];
      ASSERT_EQ(cv::countNonZero(Differs(a.mask_gt, b.mask)), 0);
      for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
          if (b.mask.at<unsigned char>(y, x) != kMaskObject) continue;
          ++object;
          const cv::Vec3b pa = a.rgb.at<cv::Vec3b>(y, x), pb = b.rgb.at<cv::Vec3b>(y, x);
          bool same = true;
          for (int k = 0; k < 3; ++k) {
            ASSERT_LE(std::abs(pa[k] - pb[k]), 1) << x << "," << y;
            same &= pa[k] == pb[k];
          }
          equal += same;
        }
      }
    }
  }
  EXPECT_GT(object, 1000);
  EXPECT_GT(equal, 0.99 * object);
}

TEST(Realism, BackgroundDiffersPerVideoAndMovesWithTheCamera) {
  SynthOptions o = CasualOptionsFor(2, 8, 64);
  o.casual.noise_read = 0;
  o.casual.noise_shot = 0;
  const SynthScene scene = RenderSyntheticScene(Quadruped(), o);
  auto background_mean = [&](int v, int f) {
    const Frame& fr = scene.dataset.videos[v].frames[f];
    return cv::mean(fr.rgb, fr.mask_gt == 0);
  };
  const cv::Scalar a = background_mean(0, 0), b = background_mean(1, 0);
  EXPECT_GT(cv::norm(a - b), 2.0) << "two videos with the same-looking world";
  // The camera moves: the background of the first and last frame differ.
  const Frame& f0 = scene.dataset.videos[0].frames[0];
  const Frame& f7 = scene.dataset.videos[0].frames[7];
  const cv::Mat both_background = (f0.mask_gt == 0) & (f7.mask_gt == 0);
  cv::Mat diff;
  cv::absdiff(f0.rgb, f7.rgb, diff);
  EXPECT_GT(cv::mean(diff, both_background)[0], 3.0);
}

// Changed pixels of a degraded mask lie within `band` px of the exact
// boundary (pixel-centre distance to the other class <= band + 0.5) or in a
// hole; returns how many lie within the band.
int CheckBoundaryBand(const cv::Mat& exact, const MaskDegradation& d, double band) {
  cv::Mat dist_in, dist_out;
  cv::distanceTransform(exact == 255, dist_in, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::distanceTransform(exact != 255, dist_out, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  int in_band = 0;
  for (int y = 0; y < exact.rows; ++y) {
    for (int x = 0; x < exact.cols; ++x) {
      if (exact.at<unsigned char>(y, x) == d.mask.at<unsigned char>(y, x)) continue;
      const bool inside = exact.at<unsigned char>(y, x) == 255;
      const float dist = inside ? dist_in.at<float>(y, x) : dist_out.at<float>(y, x);
      if (dist <= band + 0.5 + 1e-4) {
        ++in_band;
        continue;
      }
      bool in_hole = false;
      for (const cv::Vec3f& h : d.holes) {
        in_hole |= inside && std::hypot(x + 0.5 - h[0], y + 0.5 - h[1]) <= h[2] + 1e-4;
      }
      EXPECT_TRUE(in_hole) << "pixel " << x << "," << y << " changed " << dist << " px from the "
                           << "boundary, outside any hole";
    }
  }
  return in_band;
}

TEST(Realism, DegradedMaskMovesTheBoundaryByAtMostTwoPixels) {
  cv::Mat exact = cv::Mat::zeros(128, 160, CV_8UC1);
  cv::circle(exact, cv::Point(60, 64), 35, cv::Scalar(255), cv::FILLED);
  cv::rectangle(exact, cv::Rect(90, 58, 50, 12), cv::Scalar(255), cv::FILLED);  // a "leg"
  const int area = cv::countNonZero(exact);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(exact.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  const double perimeter = cv::arcLength(contours[0], true);
  CasualOptions o;
  int total_holes = 0;
  for (int trial = 0; trial < 20; ++trial) {
    std::mt19937_64 rng(1000 + trial);
    const MaskDegradation d = DegradeMask(exact, cv::Mat(), o, rng);
    EXPECT_GE(d.boundary_amplitude, 1.0);
    EXPECT_LE(d.boundary_amplitude, 2.0);
    const int changed = cv::countNonZero(Differs(exact, d.mask));
    const int in_band = CheckBoundaryBand(exact, d, o.mask_boundary_px);
    EXPECT_GT(in_band, 0.1 * perimeter) << "the boundary hardly moved";
    // Bounded area: at most the band along the boundary plus the holes.
    double hole_area = 0;
    for (const cv::Vec3f& h : d.holes) hole_area += M_PI * (h[2] + 0.5) * (h[2] + 0.5);
    EXPECT_LE(changed, 2 * 2.5 * perimeter + hole_area);
    EXPECT_LT(changed, 0.2 * area);
    EXPECT_LE(static_cast<int>(d.holes.size()), o.mask_holes_max);
    for (const cv::Vec3f& h : d.holes) {
      EXPECT_GE(h[2], 0.7f);
      EXPECT_LE(h[2], 2.0f);
      EXPECT_EQ(d.mask.at<unsigned char>(static_cast<int>(h[1]), static_cast<int>(h[0])), 0);
    }
    total_holes += static_cast<int>(d.holes.size());
    EXPECT_EQ(d.limb_pixels, 0);
  }
  EXPECT_GT(total_holes, 10);  // 0..3 per mask, 1.5 on average
  // A missing limb: its pixels are background, the rest as before.
  cv::Mat limb = cv::Mat::zeros(exact.size(), CV_8UC1);
  cv::rectangle(limb, cv::Rect(100, 58, 40, 12), cv::Scalar(255), cv::FILLED);
  std::mt19937_64 a(7), b(7);
  const MaskDegradation with_limb = DegradeMask(exact, limb, o, a);
  const MaskDegradation without = DegradeMask(exact, cv::Mat(), o, b);
  EXPECT_EQ(with_limb.limb_pixels, 40 * 12);
  EXPECT_EQ(cv::countNonZero(with_limb.mask & limb), 0);
  EXPECT_EQ(cv::countNonZero(Differs(with_limb.mask, without.mask) & ~limb), 0);
}

TEST(Realism, RenderedMasksAreDegradedWithinBoundsAndMissALimbSometimes) {
  const SynthOptions o = CasualOptionsFor(4, 25, 64);
  const SynthScene scene = RenderSyntheticScene(Quadruped(), o);
  int limb_frames = 0, frames = 0;
  for (int v = 0; v < o.num_videos; ++v) {
    for (int f = 0; f < o.frames_per_video; ++f) {
      const Frame& fr = scene.dataset.videos[v].frames[f];
      const CasualFrameRecord& r = scene.casual[v][f];
      ++frames;
      ASSERT_FALSE(fr.mask_gt.empty());
      cv::Mat dist_in, dist_out;
      cv::distanceTransform(fr.mask_gt == 255, dist_in, cv::DIST_L2, cv::DIST_MASK_PRECISE);
      cv::distanceTransform(fr.mask_gt != 255, dist_out, cv::DIST_L2, cv::DIST_MASK_PRECISE);
      int outside_band = 0;
      for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
          const bool gt = fr.mask_gt.at<unsigned char>(y, x) == 255;
          if (gt == (fr.mask.at<unsigned char>(y, x) == 255)) continue;
          const float dist = gt ? dist_in.at<float>(y, x) : dist_out.at<float>(y, x);
          if (dist > 2.5 + 1e-4) ++outside_band;
        }
      }
      if (r.limb_node >= 0) {
        ++limb_frames;
        EXPECT_GT(r.limb_pixels, 0);
        EXPECT_LE(outside_band, r.limb_pixels + r.holes * 20);
      } else {
        // Only holes (radius <= 2 px: at most 13 pixels each) away from the band.
        EXPECT_LE(outside_band, r.holes * 13) << "video " << v << " frame " << f;
      }
    }
  }
  // About 1 frame in 20 (binomial(100, 0.05): 5 +- 2.2).
  EXPECT_GE(limb_frames, 1);
  EXPECT_LE(limb_frames, 12);
}

TEST(Realism, JpegRoundTripAtQuality85) {
  SynthOptions o = CasualOptionsFor(1, 2, 64);
  const SynthScene jpeg = RenderSyntheticScene(Quadruped(), o);
  o.casual.jpeg_quality = 0;
  const SynthScene raw = RenderSyntheticScene(Quadruped(), o);
  for (int f = 0; f < 2; ++f) {
    const cv::Mat& a = jpeg.dataset.videos[0].frames[f].rgb;
    const cv::Mat& b = raw.dataset.videos[0].frames[f].rgb;
    // Everything else is drawn from the same streams: the frame is exactly
    // the quality-85 round trip of the frame without JPEG.
    EXPECT_EQ(cv::countNonZero(Differs(a, JpegRoundTrip(b, 85))), 0);
    const double psnr = cv::PSNR(a, b);
    EXPECT_GT(psnr, 25);
    EXPECT_LT(psnr, 45);
    EXPECT_GT(cv::countNonZero(Differs(a, JpegRoundTrip(b, 50))), 0);
    EXPECT_GT(cv::countNonZero(Differs(a, JpegRoundTrip(b, 95))), 0);
  }
}

TEST(Realism, SensorNoiseHasTheModelledStatistics) {
  for (double level : {10.0, 120.0, 230.0}) {
    cv::Mat image(256, 256, CV_32FC3, cv::Scalar::all(level));
    std::mt19937_64 rng(3);
    AddSensorNoise(&image, 1.5, 0.25, 1.2, rng);
    cv::Scalar mean, stddev;
    cv::meanStdDev(image.reshape(1), mean, stddev);
    const double expected = 1.2 * std::sqrt(1.5 * 1.5 + 0.25 * level);
    // 196608 samples: the standard error of the std is ~0.16 %.
    EXPECT_NEAR(stddev[0], expected, 0.01 * expected) << "level " << level;
    EXPECT_NEAR(mean[0], level, 5 * expected / std::sqrt(196608.0)) << "level " << level;
  }
}

TEST(Realism, MotionBlurAveragesSubFrames) {
  SynthOptions o = CasualOptionsFor(1, 40, 64);
  o.casual.noise_read = 0;
  o.casual.noise_shot = 0;
  o.casual.jpeg_quality = 0;
  const SynthScene blurred = RenderSyntheticScene(Quadruped(), o);
  o.casual.blur_subframes = 1;
  const SynthScene sharp = RenderSyntheticScene(Quadruped(), o);
  auto detail = [](const cv::Mat& rgb) {
    cv::Mat grey, lap;
    cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
    cv::Laplacian(grey, lap, CV_32F);
    return cv::mean(cv::abs(lap))[0];
  };
  for (int f : {5, 20, 35}) {
    const Frame& a = blurred.dataset.videos[0].frames[f];
    const Frame& b = sharp.dataset.videos[0].frames[f];
    // The ground truth is the frame's instant either way.
    EXPECT_EQ(cv::countNonZero(Differs(a.mask_gt, b.mask_gt)), 0);
    EXPECT_EQ(cv::countNonZero(Differs(a.depth, b.depth)), 0);
    // Averaging sub-frames changes the picture and smooths it.
    cv::Mat diff;
    cv::absdiff(a.rgb, b.rgb, diff);
    EXPECT_GT(cv::mean(diff)[0], 1.0) << "frame " << f;
    EXPECT_LT(detail(a.rgb), 0.9 * detail(b.rgb)) << "frame " << f;
  }
}

TEST(Realism, SameSeedSameBytesOtherSeedOtherFrames) {
  SynthOptions o = CasualOptionsFor(2, 3, 48);
  const SynthScene a = RenderSyntheticScene(Quadruped(), o);
  const SynthScene b = RenderSyntheticScene(Quadruped(), o);
  o.seed = 12;
  const SynthScene c = RenderSyntheticScene(Quadruped(), o);
  for (int v = 0; v < 2; ++v) {
    for (int f = 0; f < 3; ++f) {
      const Frame& fa = a.dataset.videos[v].frames[f];
      const Frame& fb = b.dataset.videos[v].frames[f];
      const Frame& fc = c.dataset.videos[v].frames[f];
      EXPECT_EQ(cv::countNonZero(Differs(fa.rgb, fb.rgb)), 0);
      EXPECT_EQ(cv::countNonZero(Differs(fa.mask, fb.mask)), 0);
      EXPECT_GT(cv::countNonZero(Differs(fa.rgb, fc.rgb)), 100);
    }
  }
}

TEST(Realism, DatasetKeepsGroundTruthApartAndLoads) {
  const SynthOptions o = CasualOptionsFor(2, 3, 40);
  const SynthScene scene = RenderSyntheticScene(Quadruped(), o);
  const std::string dir = ::testing::TempDir() + "/realism_dataset";
  std::filesystem::remove_all(dir);
  WriteDataset(scene.dataset, dir, &scene.gt_meshes);
  EXPECT_FALSE(std::filesystem::exists(dir + "/video_000/features"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/video_000/mask_gt/00002.png"));
  LoadOptions load;
  load.load_mask_gt = true;
  const Dataset loaded = LoadDataset(dir, load);
  for (int v = 0; v < 2; ++v) {
    const Video& video = loaded.videos[v];
    EXPECT_TRUE(video.present.mask_gt);
    EXPECT_FALSE(video.present.features);
    ASSERT_TRUE(video.intrinsics_gt.has_value());
    EXPECT_NEAR((*video.intrinsics_gt - *scene.dataset.videos[v].intrinsics_gt).norm(), 0, 1e-9);
    for (int f = 0; f < 3; ++f) {
      EXPECT_EQ(cv::countNonZero(
                    Differs(video.frames[f].mask_gt, scene.dataset.videos[v].frames[f].mask_gt)),
                0);
      EXPECT_EQ(
          cv::countNonZero(Differs(video.frames[f].mask, scene.dataset.videos[v].frames[f].mask)),
          0);
    }
  }
  // Without load_mask_gt the files are checked by header only.
  const Dataset quick = LoadDataset(dir);
  EXPECT_TRUE(quick.videos[0].frames[0].mask_gt.empty());
  std::filesystem::remove_all(dir);
}

TEST(Realism, PlainRendersHaveNoGroundTruthExtras) {
  SynthOptions o = CasualOptionsFor(1, 2, 32);
  o.realism = Realism::kNone;
  const SynthScene scene = RenderSyntheticScene(Quadruped(), o);
  EXPECT_FALSE(scene.dataset.videos[0].intrinsics_gt.has_value());
  EXPECT_TRUE(scene.dataset.videos[0].frames[0].mask_gt.empty());
  EXPECT_FALSE(scene.dataset.videos[0].frames[0].features.empty());
  EXPECT_TRUE(scene.casual.empty());
}

TEST(Realism, BadOptionsNameTheField) {
  SynthOptions o = CasualOptionsFor(1, 2, 32);
  o.pose_noise_deg = 10;
  try {
    o.Check();
    FAIL() << "pose noise accepted with realism casual";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("pose_noise_deg"), std::string::npos) << e.what();
  }
  o.pose_noise_deg = 0;
  o.casual.focal_min = 2;  // above focal_max
  try {
    o.Check();
    FAIL() << "focal_min > focal_max accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("focal_min"), std::string::npos) << e.what();
  }
  o.casual = CasualOptions();
  o.casual.jpeg_quality = 101;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace banmo::synth
