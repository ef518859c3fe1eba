// The pose-noise models of `banmo synth` (docs/synth.md, "Pose noise"):
// the Gaussian model's mean rotation angle against an independent quadrature
// and against sampling, the exact model's fixed angle, the translation
// handling, determinism in the seed, option errors and the recorded error.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "banmo/geometry/se3.h"
#include "banmo/io/dataset.h"
#include "banmo/synth/features.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"
#include "banmo/util/enum_names.h"
#include "banmo/util/error.h"

namespace banmo::synth {
namespace {

constexpr double kDeg = M_PI / 180;

// Small angles never wrap: the mean is the Maxwell mean 2 sigma sqrt(2 / pi).
TEST(GaussianPoseNoise, SmallSigmaIsTheMaxwellMean) {
  for (double sigma_deg : {0.5, 5.0, 20.0}) {
    const double sigma = sigma_deg * kDeg;
    EXPECT_NEAR(GaussianNoiseMeanAngle(sigma), 2 * sigma * std::sqrt(2 / M_PI), 1e-13 * sigma)
        << sigma_deg;
  }
  EXPECT_EQ(GaussianNoiseMeanAngle(0), 0);
  EXPECT_EQ(GaussianNoiseSigma(0), 0);
}

// Reference values from an independent computation (composite Simpson, 20000
// intervals on [0, 12 sigma], of the Maxwell density times the folded angle
// |((r + pi) mod 2 pi) - pi|, then bisection), in degrees: sigma 12.5331 /
// 31.3329 / 56.8036 for a mean of 20 / 50 / 90, peak mean 122.5555 near
// sigma 99.2. The naive inversion sigma = mean / (2 sqrt(2 / pi)) is
// 56.3991 for 90: the wrap matters there and nowhere below 50.
TEST(GaussianPoseNoise, SigmaTableAndPeakMatchAnIndependentQuadrature) {
  EXPECT_NEAR(GaussianNoiseSigma(20 * kDeg) / kDeg, 12.5331, 1e-3);
  EXPECT_NEAR(GaussianNoiseSigma(50 * kDeg) / kDeg, 31.3329, 1e-3);
  EXPECT_NEAR(GaussianNoiseSigma(90 * kDeg) / kDeg, 56.8036, 1e-3);
  for (double deg : {1.0, 20.0, 50.0, 90.0, 120.0}) {
    EXPECT_NEAR(GaussianNoiseMeanAngle(GaussianNoiseSigma(deg * kDeg)), deg * kDeg, 1e-12) << deg;
  }
  const GaussianNoisePeak peak = GaussianNoiseMaximum();
  EXPECT_NEAR(peak.mean_angle / kDeg, 122.5555, 1e-3);
  EXPECT_NEAR(peak.sigma / kDeg, 99.2, 0.5);
  // Increasing up to the peak (what the bisection relies on), then falling
  // towards pi / 2 (the folded angle becomes uniform on [0, pi]).
  double previous = 0;
  for (int i = 1; i <= 400; ++i) {
    const double m = GaussianNoiseMeanAngle(peak.sigma * i / 400);
    EXPECT_GT(m, previous) << i;
    previous = m;
  }
  EXPECT_LT(GaussianNoiseMeanAngle(3.0), peak.mean_angle - 10 * kDeg);
  EXPECT_NEAR(GaussianNoiseMeanAngle(20.0), M_PI / 2, 1e-3);
  // Above the peak there is no sigma: an error naming the reachable maximum.
  try {
    GaussianNoiseSigma(123 * kDeg);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("122.55"), std::string::npos) << e.what();
  }
}

// Sample mean of the rotation angle of `n` draws (angle measured by Eigen's
// AngleAxis of the drawn matrix, independent of the folding formula) and its
// standard error.
struct SampleMean {
  double mean = 0;
  double standard_error = 0;
};
SampleMean SampleAngles(PoseNoiseModel model, double angle, double sigma, int n,
                        std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Matrix3d r = DrawPoseNoiseRotation(model, angle, sigma, rng);
    EXPECT_NEAR((r.transpose() * r - Eigen::Matrix3d::Identity()).norm(), 0, 1e-12);
    const double a = Eigen::AngleAxisd(r).angle();
    sum += a;
    sum2 += a * a;
  }
  SampleMean s;
  s.mean = sum / n;
  s.standard_error = std::sqrt(std::max(0.0, sum2 / n - s.mean * s.mean) / n);
  return s;
}

// The mean rotation error of the drawn noise is DEG: 200000 draws, tolerance
// 4 standard errors of the sample mean (0.02 / 0.07 / 0.09 deg at 20 / 50 /
// 90). The naive (unwrapped) sigma misses 90 deg by 0.6 deg (mean 89.40), far outside
// the tolerance, so this test sees a wrong inversion.
TEST(GaussianPoseNoise, SampleMeanIsTheRequestedMean) {
  constexpr int kDraws = 200000;
  for (double deg : {20.0, 50.0, 90.0}) {
    const double sigma = GaussianNoiseSigma(deg * kDeg);
    const SampleMean s =
        SampleAngles(PoseNoiseModel::kGaussian, 0, sigma, kDraws, 11 + static_cast<int>(deg));
    std::printf("mean %5.1f deg: sigma %.4f deg, sample mean %.4f deg +- %.4f (1 SE)\n", deg,
                sigma / kDeg, s.mean / kDeg, s.standard_error / kDeg);
    EXPECT_NEAR(s.mean / kDeg, deg, 4 * s.standard_error / kDeg) << deg;
  }
  const double naive_sigma = 90 * kDeg / (2 * std::sqrt(2 / M_PI));
  const SampleMean naive = SampleAngles(PoseNoiseModel::kGaussian, 0, naive_sigma, kDraws, 11);
  EXPECT_GT(std::abs(naive.mean / kDeg - 90), 4 * naive.standard_error / kDeg);
}

TEST(ExactPoseNoise, EveryDrawIsTheAngle) {
  std::mt19937_64 rng(5);
  for (double deg : {0.0, 20.0, 90.0, 179.0}) {
    for (int i = 0; i < 1000; ++i) {
      const Eigen::Matrix3d r = DrawPoseNoiseRotation(PoseNoiseModel::kExact, deg * kDeg, 0, rng);
      EXPECT_NEAR(Eigen::AngleAxisd(r).angle(), deg * kDeg, 1e-9) << deg;
    }
  }
}

SynthOptions FewFrames(PoseNoiseModel model, double deg) {
  SynthOptions o;
  o.num_videos = 2;
  o.frames_per_video = 6;
  o.pose_noise_deg = deg;
  o.pose_noise_model = model;
  o.seed = 4;
  return o;
}

// Scene level: `exact` rotates every frame by exactly DEG about the object
// centre and keeps the translation bit for bit; `gaussian` puts the centre at
// (0, 0, camera_distance).
TEST(PoseNoiseScene, ExactKeepsTranslationGaussianResetsIt) {
  const Rig rig = LoadRig("quadruped");
  for (double deg : {20.0, 90.0, 180.0}) {
    const ScenePlan plan = PlanScene(rig, FewFrames(PoseNoiseModel::kExact, deg));
    for (const auto& video : plan.frames) {
      for (const FramePlan& fp : video) {
        EXPECT_NEAR(
            RotationAngleBetween(fp.camera_from_root_gt.data(), fp.camera_from_root_init.data()),
            deg * kDeg, 1e-9);
        EXPECT_TRUE(fp.camera_from_root_init.tail<3>() == fp.camera_from_root_gt.tail<3>());
      }
    }
  }
  SynthOptions o = FewFrames(PoseNoiseModel::kGaussian, 50);
  o.camera_distance = 4;
  const ScenePlan plan = PlanScene(rig, o);
  for (const auto& video : plan.frames) {
    for (const FramePlan& fp : video) {
      EXPECT_TRUE(fp.camera_from_root_init.tail<3>() == Eigen::Vector3d(0, 0, 4));
      // The GT centre is off the axis and ~4 +- 5 % away: a real error.
      EXPECT_GT((fp.camera_from_root_gt.tail<3>() - Eigen::Vector3d(0, 0, 4)).norm(), 1e-3);
    }
  }
}

TEST(PoseNoiseScene, GaussianIsDeterministicInTheSeed) {
  const Rig rig = LoadRig("quadruped");
  SynthOptions o = FewFrames(PoseNoiseModel::kGaussian, 50);
  const ScenePlan a = PlanScene(rig, o), b = PlanScene(rig, o);
  std::vector<double> angles;
  for (size_t v = 0; v < a.frames.size(); ++v) {
    for (size_t f = 0; f < a.frames[v].size(); ++f) {
      EXPECT_TRUE(a.frames[v][f].camera_from_root_init == b.frames[v][f].camera_from_root_init);
      angles.push_back(RotationAngleBetween(a.frames[v][f].camera_from_root_gt.data(),
                                            a.frames[v][f].camera_from_root_init.data()));
    }
  }
  // Gaussian angles differ from frame to frame (exact ones would not).
  EXPECT_GT(*std::max_element(angles.begin(), angles.end()) -
                *std::min_element(angles.begin(), angles.end()),
            5 * kDeg);
  o.seed += 1;
  const ScenePlan c = PlanScene(rig, o);
  EXPECT_GT((a.frames[0][0].camera_from_root_init - c.frames[0][0].camera_from_root_init).norm(),
            1e-3);
  // The noise stream is the same for both models' seeds but the draws differ:
  // switching the model changes the rough poses.
  const ScenePlan e = PlanScene(rig, FewFrames(PoseNoiseModel::kExact, 50));
  EXPECT_GT((a.frames[0][0].camera_from_root_init - e.frames[0][0].camera_from_root_init).norm(),
            1e-3);
}

TEST(PoseNoiseOptions, NamesAndRanges) {
  EXPECT_STREQ(EnumName(PoseNoiseModel::kExact), "exact");
  EXPECT_EQ(ParseEnum<PoseNoiseModel>("gaussian"), PoseNoiseModel::kGaussian);
  EXPECT_FALSE(ParseEnum<PoseNoiseModel>("Gaussian").has_value());
  EXPECT_EQ(EnumChoices<PoseNoiseModel>(), "{exact, gaussian}");
  EXPECT_EQ(SynthOptions().pose_noise_model, PoseNoiseModel::kExact);
  SynthOptions o = FewFrames(PoseNoiseModel::kGaussian, 122.5);
  EXPECT_NO_THROW(o.Check());
  o.pose_noise_deg = 123;
  try {
    o.Check();
    FAIL();
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("pose_noise_deg"), std::string::npos) << what;
    EXPECT_NE(what.find("122.55"), std::string::npos) << what;
  }
  o.pose_noise_model = PoseNoiseModel::kExact;
  EXPECT_NO_THROW(o.Check());  // up to 180 for exact
}

// MeasurePoseNoise: mean, nearest-rank p90 and max of known errors.
TEST(PoseNoiseStats, MeanP90AndMaxOfKnownErrors) {
  Dataset d;
  d.videos.resize(2);
  for (int i = 1; i <= 10; ++i) {
    Frame frame;
    frame.root_pose_gt =
        PoseFromAngleAxis(Eigen::Vector3d(0.3, -0.2, 0.1), Eigen::Vector3d(0, 0, 3));
    const Eigen::Isometry3d gt = IsometryFromPose(frame.root_pose_gt->data());
    Eigen::Isometry3d noise = Eigen::Isometry3d::Identity();
    noise.linear() = Eigen::AngleAxisd(i * kDeg, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
    Eigen::Isometry3d init = gt * noise;
    init.translation() += Eigen::Vector3d(0, 0.01 * i, 0);
    frame.root_pose_init = PoseFromIsometry(init);
    d.videos[i <= 4 ? 0 : 1].frames.push_back(frame);
  }
  Frame no_gt;  // frames without ground truth are not counted
  d.videos[1].frames.push_back(no_gt);
  const PoseNoiseStats all = MeasurePoseNoise(d);
  EXPECT_EQ(all.frames, 10);
  EXPECT_NEAR(all.rotation_mean_deg, 5.5, 1e-9);
  EXPECT_NEAR(all.rotation_p90_deg, 9, 1e-9);
  EXPECT_NEAR(all.rotation_max_deg, 10, 1e-9);
  EXPECT_NEAR(all.translation_mean, 0.055, 1e-12);
  EXPECT_NEAR(all.translation_p90, 0.09, 1e-12);
  const PoseNoiseStats first = MeasurePoseNoise(d, 0);
  EXPECT_EQ(first.frames, 4);
  EXPECT_NEAR(first.rotation_mean_deg, 2.5, 1e-9);
  EXPECT_NEAR(first.rotation_p90_deg, 4, 1e-9);  // ceil(0.9 * 4) = 4th smallest
}

// The rendered dataset records the model and the measured error in each
// video's root_poses_init.txt (comment lines the loader skips); without
// noise nothing is added.
TEST(PoseNoiseScene, RecordedInTheRoughPoseFile) {
  const Rig rig = LoadRig("quadruped");
  SynthOptions o = FewFrames(PoseNoiseModel::kGaussian, 50);
  o.frames_per_video = 3;
  o.image_size = 16;
  o.flow_gaps = {1};
  const SynthScene scene = RenderSyntheticScene(rig, o);
  const std::string& note = scene.dataset.videos[1].root_poses_init_comment;
  EXPECT_NE(note.find("gaussian, mean 50 deg (per-axis sigma 31.33"), std::string::npos) << note;
  EXPECT_NE(note.find("translation reset to (0, 0, 3)"), std::string::npos) << note;
  EXPECT_NE(note.find("this video (3 frames): rotation error mean"), std::string::npos) << note;
  EXPECT_NE(note.find("all videos (6 frames)"), std::string::npos) << note;
  const std::string dir = ::testing::TempDir() + "/pose_noise_recorded_" + std::to_string(getpid());
  WriteDataset(scene.dataset, dir, &scene.gt_meshes, true);
  const Dataset loaded = LoadDataset(dir);
  for (int f = 0; f < 3; ++f) {
    EXPECT_TRUE(loaded.videos[1].frames[f].root_pose_init ==
                scene.dataset.videos[1].frames[f].root_pose_init);
  }
  std::ifstream in(dir + "/video_001/root_poses_init.txt");
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(text.find("\n# banmo synth pose noise: gaussian"), std::string::npos) << text;
  std::filesystem::remove_all(dir);
  o.pose_noise_deg = 0;
  o.pose_noise_model = PoseNoiseModel::kExact;
  EXPECT_TRUE(RenderSyntheticScene(rig, o).dataset.videos[0].root_poses_init_comment.empty());
}

}  // namespace
}  // namespace banmo::synth
