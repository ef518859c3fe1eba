#include "banmo/registration/root_init_registration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "banmo/registration/root_pose_error.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"

namespace banmo {
namespace {

// The built-in quadruped, 2 videos x 12 frames at 96 px (the default
// scene's camera paths, features with their default noise), rendered once.
const Dataset& Rendered() {
  static const Dataset* dataset = [] {
    synth::SynthOptions options;
    options.num_videos = 2;
    options.frames_per_video = 12;
    options.image_size = 96;
    options.flow_gaps = {1};
    options.seed = 3;
    return new Dataset(synth::RenderSyntheticScene(synth::LoadRig("quadruped"), options).dataset);
  }();
  return *dataset;
}

// The rendered scene with every initial root pose replaced by what `banmo
// prepare` writes without --poses: identity rotation, object 3 units ahead.
Dataset WithoutPoses() {
  Dataset d = Rendered();
  for (Video& v : d.videos) {
    for (Frame& f : v.frames) {
      f.root_pose_init = PoseIdentity();
      f.root_pose_init[kPoseT + 2] = 3.0;
    }
  }
  return d;
}

TEST(RootPosesCarryRotation, IdenticalPosesCarryNone) {
  Dataset d = WithoutPoses();
  EXPECT_FALSE(RootPosesCarryRotation(d));
  // Translations alone carry no rotation.
  d.videos[1].frames[4].root_pose_init[kPoseT] = 0.5;
  EXPECT_FALSE(RootPosesCarryRotation(d));
  // A skipped frame's pose is not data.
  Frame& f = d.videos[1].frames[5];
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  f.root_pose_init.head<4>() << q.w(), q.x(), q.y(), q.z();
  f.skip = true;
  EXPECT_FALSE(RootPosesCarryRotation(d));
  f.skip = false;
  EXPECT_TRUE(RootPosesCarryRotation(d));
  EXPECT_TRUE(RootPosesCarryRotation(Rendered()));
}

// From identity poses (errors of 50-180 deg) to the true rotations within a
// few degrees: the default scene registers to 4.6 deg mean (120 frames at
// 128 px); this smaller one has fewer pixels per frame, hence the looser
// bound. The depth reversal must fit clearly worse.
TEST(RootInitRegistration, RegistersFramesWithoutPoses) {
  Dataset d = WithoutPoses();
  const std::optional<RootPoseErrors> before = InitialRootPoseErrors(d);
  ASSERT_TRUE(before);
  EXPECT_GT(before->mean_deg, 30.0);
  const RootRegistration r = RegisterRootPoseInit(RootRegistrationOptions(), &d);
  ASSERT_TRUE(r.registered) << r.reason;
  EXPECT_EQ(r.frames + r.filled, 24);
  EXPECT_GT(r.observations_per_frame, 30.0);
  EXPECT_LT(r.median_residual_px, 2.0);
  EXPECT_LT(r.cost, 0.8 * r.mirror_cost);
  const std::optional<RootPoseErrors> after = InitialRootPoseErrors(d);
  ASSERT_TRUE(after);
  EXPECT_LT(after->mean_deg, 10.0);
  EXPECT_LT(after->p90_deg, 20.0);
  // Scale: the median depth is the initial poses' (3 units); the true
  // depths are about 3 too (camera distance 3).
  std::vector<double> z;
  for (const Video& v : d.videos) {
    for (const Frame& f : v.frames) z.push_back(f.root_pose_init[kPoseT + 2]);
  }
  std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
  EXPECT_NEAR(z[z.size() / 2], 3.0, 1e-9);
}

// Deterministic: a resumed solve must get the same poses.
TEST(RootInitRegistration, IsDeterministic) {
  Dataset a = WithoutPoses(), b = WithoutPoses();
  ASSERT_TRUE(RegisterRootPoseInit(RootRegistrationOptions(), &a).registered);
  ASSERT_TRUE(RegisterRootPoseInit(RootRegistrationOptions(), &b).registered);
  for (size_t v = 0; v < a.videos.size(); ++v) {
    for (size_t t = 0; t < a.videos[v].frames.size(); ++t) {
      EXPECT_EQ(a.videos[v].frames[t].root_pose_init, b.videos[v].frames[t].root_pose_init);
    }
  }
}

// Exact poses are smoother than the registration: kept exactly as they are.
TEST(RootInitRegistration, KeepsExactPoses) {
  Dataset d = Rendered();
  for (Video& v : d.videos) {
    for (Frame& f : v.frames) f.root_pose_init = *f.root_pose_gt;
  }
  const RootRegistration r = RegisterRootPoseInit(RootRegistrationOptions(), &d);
  ASSERT_TRUE(r.registered) << r.reason;
  ASSERT_EQ(r.videos.size(), 2u);
  for (const VideoRegistration& c : r.videos) {
    EXPECT_FALSE(c.replaced);
    EXPECT_LT(c.initial_noise_deg, c.registered_noise_deg);
  }
  for (const Video& v : d.videos) {
    for (const Frame& f : v.frames) EXPECT_EQ(f.root_pose_init, *f.root_pose_gt);
  }
}

// Rough poses (each turned by 30 deg about a random axis) are replaced, and
// the registration is aligned to them: the given poses fix the gauge, so
// the registered poses are near the true ones even without a global
// alignment.
// With `always`, exact poses are replaced too, and stay within the
// registration's accuracy of the truth (no global turn or scale).
TEST(RootInitRegistration, ReplacesRoughPosesAlignedToThem) {
  for (const bool always : {false, true}) {
    Dataset d = Rendered();
    std::mt19937_64 rng(11);
    std::normal_distribution<double> normal;
    for (Video& v : d.videos) {
      for (Frame& f : v.frames) {
        f.root_pose_init = *f.root_pose_gt;
        if (always) continue;
        const Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
        const Eigen::Quaterniond q =
            Eigen::Quaterniond(f.root_pose_init[0], f.root_pose_init[1], f.root_pose_init[2],
                               f.root_pose_init[3]) *
            Eigen::Quaterniond(Eigen::AngleAxisd(30 * M_PI / 180, axis.normalized()));
        f.root_pose_init.head<4>() << q.w(), q.x(), q.y(), q.z();
      }
    }
    RootRegistrationOptions options;
    options.always = always;
    const RootRegistration r = RegisterRootPoseInit(options, &d);
    ASSERT_TRUE(r.registered) << r.reason;
    for (const VideoRegistration& c : r.videos) {
      EXPECT_TRUE(c.replaced);
      if (!always) {
        EXPECT_GT(c.initial_noise_deg, 5 * c.registered_noise_deg);
      }
    }
    double sum = 0, depth = 0;
    int n = 0;
    for (const Video& v : d.videos) {
      for (const Frame& f : v.frames) {
        const Eigen::Quaterniond a(f.root_pose_init[0], f.root_pose_init[1], f.root_pose_init[2],
                                   f.root_pose_init[3]);
        const Eigen::Quaterniond b((*f.root_pose_gt)[0], (*f.root_pose_gt)[1], (*f.root_pose_gt)[2],
                                   (*f.root_pose_gt)[3]);
        sum += a.normalized().angularDistance(b.normalized()) * 180 / M_PI;
        depth += std::abs(f.root_pose_init[kPoseT + 2] - (*f.root_pose_gt)[kPoseT + 2]);
        ++n;
      }
    }
    // The gauge comes from the rough poses' offsets, each 30 deg off: their
    // L1 mean over 24 frames is itself a few degrees off. Exact poses fix it.
    EXPECT_LT(sum / n, always ? 10.0 : 20.0) << "always " << always;
    const std::optional<RootPoseErrors> aligned = InitialRootPoseErrors(d);
    ASSERT_TRUE(aligned);
    EXPECT_LT(aligned->mean_deg, 10.0);
    EXPECT_LT(depth / n, 0.3);  // the registration's origin is the features' centroid
  }
}

TEST(RootInitRegistration, NeedsFeaturesInEveryFrame) {
  Dataset d = WithoutPoses();
  d.videos[1].frames[3].features = cv::Mat();
  const Dataset before = d;
  const RootRegistration r = RegisterRootPoseInit(RootRegistrationOptions(), &d);
  EXPECT_FALSE(r.registered);
  EXPECT_NE(r.reason.find("video_001 frame 3 has no features"), std::string::npos) << r.reason;
  for (size_t v = 0; v < d.videos.size(); ++v) {
    for (size_t t = 0; t < d.videos[v].frames.size(); ++t) {
      EXPECT_EQ(d.videos[v].frames[t].root_pose_init, before.videos[v].frames[t].root_pose_init);
    }
  }
}

// Features that cover part of the mask: an all-zero feature is none
// (IsPixelFeature), so its pixel registers as if it were outside the mask.
// Exact equality: the registration reads the mask only to list the object
// pixels' features, and both datasets list the same ones.
TEST(RootInitRegistration, SkipsObjectPixelsWithoutFeatures) {
  Dataset partial = WithoutPoses();
  Dataset cut = partial;
  int zeroed = 0;
  for (size_t v = 0; v < partial.videos.size(); ++v) {
    for (size_t t = 0; t < partial.videos[v].frames.size(); ++t) {
      Frame& f = partial.videos[v].frames[t];
      Frame& g = cut.videos[v].frames[t];
      const cv::Rect left(0, 0, f.mask.cols / 2, f.mask.rows);
      zeroed += cv::countNonZero(f.mask(left) == kMaskObject);
      // Clones: the copies share pixels with Rendered().
      f.features = f.features.clone();
      f.features(left) = cv::Scalar::all(0);  // zero outside the mask already
      g.mask = g.mask.clone();
      g.mask(left).setTo(kMaskBackground);
    }
  }
  ASSERT_GT(zeroed, 1000);
  const RootRegistration a = RegisterRootPoseInit(RootRegistrationOptions(), &partial);
  const RootRegistration b = RegisterRootPoseInit(RootRegistrationOptions(), &cut);
  ASSERT_TRUE(a.registered) << a.reason;
  EXPECT_EQ(a.references, b.references);
  EXPECT_EQ(a.observations_per_frame, b.observations_per_frame);
  EXPECT_EQ(a.cost, b.cost);
  for (size_t v = 0; v < partial.videos.size(); ++v) {
    for (size_t t = 0; t < partial.videos[v].frames.size(); ++t) {
      EXPECT_EQ(partial.videos[v].frames[t].root_pose_init, cut.videos[v].frames[t].root_pose_init)
          << "video " << v << " frame " << t;
    }
  }
}

// Feature files that are zero everywhere carry no feature: nothing to
// match, the poses stay and the reason says so.
TEST(RootInitRegistration, AllZeroFeaturesRegisterNothing) {
  Dataset d = WithoutPoses();
  for (Video& v : d.videos) {
    for (Frame& f : v.frames) f.features = cv::Mat::zeros(f.features.size(), f.features.type());
  }
  const RootRegistration r = RegisterRootPoseInit(RootRegistrationOptions(), &d);
  EXPECT_FALSE(r.registered);
  EXPECT_EQ(r.reason, "no frame has 6 observations");
  EXPECT_EQ(d.videos[1].frames[4].root_pose_init,
            WithoutPoses().videos[1].frames[4].root_pose_init);
}

// One usable frame: nothing to register against; the poses stay.
TEST(RootInitRegistration, NeedsTwoUsableFrames) {
  Dataset d = WithoutPoses();
  for (Video& v : d.videos) {
    for (Frame& f : v.frames) f.skip = true;
  }
  d.videos[0].frames[0].skip = false;
  const RootRegistration r = RegisterRootPoseInit(RootRegistrationOptions(), &d);
  EXPECT_FALSE(r.registered);
  EXPECT_EQ(r.reason, "fewer than 2 usable frames");
  EXPECT_EQ(d.videos[0].frames[0].root_pose_init,
            WithoutPoses().videos[0].frames[0].root_pose_init);
}

}  // namespace
}  // namespace banmo
