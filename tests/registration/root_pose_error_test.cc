#include "banmo/registration/root_pose_error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace banmo {
namespace {

constexpr double kDeg = M_PI / 180.0;

// One video of `n` frames with random ground-truth poses; the initial poses
// are the ground truth turned by `global` on the object side (G_gt A).
Dataset PosedDataset(int n, const Eigen::Vector3d& global) {
  Dataset d;
  d.videos.resize(1);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  const Pose a = PoseFromAngleAxis(global, Eigen::Vector3d::Zero());
  for (int t = 0; t < n; ++t) {
    Frame f;
    f.index = t;
    f.root_pose_gt = PoseFromAngleAxis(Eigen::Vector3d(normal(rng), normal(rng), normal(rng)),
                                       Eigen::Vector3d(0, 0, 3));
    PoseCompose(f.root_pose_gt->data(), a.data(), f.root_pose_init.data());
    d.videos[0].frames.push_back(f);
  }
  return d;
}

TEST(RootPoseErrors, AGlobalTurnIsAlignedAway) {
  const Dataset d = PosedDataset(20, Eigen::Vector3d(0.3, -0.5, 0.2));
  const std::optional<RootPoseErrors> e = InitialRootPoseErrors(d);
  ASSERT_TRUE(e.has_value());
  ASSERT_EQ(e->frames.size(), 20u);
  // Exact up to rounding (a few 1e-16 rad).
  EXPECT_LT(e->max_deg, 1e-9);
  EXPECT_NEAR(e->alignment_deg, Eigen::Vector3d(0.3, -0.5, 0.2).norm() / kDeg, 1e-6);
}

// Two videos each turned by its own rotation: wrong against each other
// (the global error), right within each (the per-video one).
TEST(RootPoseErrors, EachVideoAlignedOnItsOwn) {
  Dataset d = PosedDataset(12, Eigen::Vector3d(0.3, -0.5, 0.2));
  Dataset other = PosedDataset(12, Eigen::Vector3d(-1.0, 0.4, 0.9));
  d.videos.push_back(other.videos[0]);
  const std::optional<RootPoseErrors> e = InitialRootPoseErrors(d);
  ASSERT_TRUE(e.has_value());
  ASSERT_EQ(e->frames.size(), 24u);
  EXPECT_GT(e->mean_deg, 20.0);  // the two turns are 98 deg apart
  EXPECT_LT(e->video_aligned_mean_deg, 1e-9);
  for (const RootPoseErrors::FrameError& f : e->frames) EXPECT_LT(f.video_rotation_deg, 1e-9);
}

TEST(RootPoseErrors, OneFrameOffShowsInItsRowAndTheStatistics) {
  Dataset d = PosedDataset(10, Eigen::Vector3d::Zero());
  Frame& f = d.videos[0].frames[4];
  const Pose turn = PoseFromAngleAxis(Eigen::Vector3d(0, 30 * kDeg, 0), Eigen::Vector3d::Zero());
  const Pose before = f.root_pose_init;
  PoseCompose(before.data(), turn.data(), f.root_pose_init.data());
  d.videos[0].frames[7].skip = true;  // skipped frames are left out
  const std::optional<RootPoseErrors> e = InitialRootPoseErrors(d);
  ASSERT_TRUE(e.has_value());
  ASSERT_EQ(e->frames.size(), 9u);
  // The alignment absorbs about 1/9 of the turn (chordal mean), so frame 4
  // shows about 8/9 of 30 deg and the others about 30/9 deg each.
  EXPECT_NEAR(e->frames[4].rotation_deg, 30.0 * 8 / 9, 0.5);
  EXPECT_NEAR(e->frames[0].rotation_deg, 30.0 / 9, 0.5);
  EXPECT_EQ(e->max_deg, e->frames[4].rotation_deg);
  EXPECT_EQ(e->p90_deg, e->frames[4].rotation_deg);  // rank ceil(0.9 * 9) = 9
  const std::string csv = RootPoseErrorsCsv(*e);
  EXPECT_EQ(csv.rfind("video,frame,rotation_error_deg\n0,0,", 0), 0u) << csv;
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 10);
}

// The gauge freedom of a frame: all its bones turned by M and its root by
// M^-1 change no residual. The root's error sees the turn; the body's
// (root x mean bone rotation) does not.
TEST(BodyPoseErrors, DoNotSeeATurnHandedFromTheRootToTheBones) {
  const Dataset d = PosedDataset(8, Eigen::Vector3d::Zero());
  ModelOptions options;
  options.num_bones = 3;
  PinholeCamera camera;
  camera.width = camera.height = 16;
  Model model(options, std::vector<int>{8}, std::vector<PinholeCamera>{camera});
  for (int t = 0; t < 8; ++t) model.frame(0, t).root_init = *d.videos[0].frames[t].root_pose_gt;
  // Frame 3: bones turned by 40 deg (and different articulations added on
  // top, a turn per bone on the object side), the root by the inverse.
  const Pose m = PoseFromAngleAxis(Eigen::Vector3d(0, 0, 40 * kDeg), Eigen::Vector3d(0.1, 0, 0));
  Pose m_inv;
  PoseInverse(m.data(), m_inv.data());
  model.frame(0, 3).root_delta = m_inv;
  for (int b = 0; b < 3; ++b) {
    const Pose own =
        PoseFromAngleAxis(Eigen::Vector3d(0.1 * (b - 1), 0, 0), Eigen::Vector3d::Zero());
    PoseCompose(m.data(), own.data(), model.frame(0, 3).bones_t.data() + kPoseSize * b);
  }
  const std::optional<RootPoseErrors> root = ComputeRootPoseErrors(model, d);
  const std::optional<RootPoseErrors> body = ComputeBodyPoseErrors(model, d);
  ASSERT_TRUE(root.has_value() && body.has_value());
  EXPECT_GT(root->frames[3].rotation_deg, 30.0);  // 40 deg less the alignment's share
  // The own turns (-0.1, 0, 0.1 rad about x) average to the identity, so
  // the body pose is the ground truth: rounding only.
  EXPECT_LT(body->max_deg, 1e-6);
  const std::string csv = RootPoseErrorsCsv(*root, &*body);
  EXPECT_EQ(csv.rfind("video,frame,rotation_error_deg,body_rotation_error_deg\n0,0,", 0), 0u)
      << csv;
}

TEST(RootPoseErrors, NoneWithoutGroundTruth) {
  Dataset d = PosedDataset(3, Eigen::Vector3d::Zero());
  for (Frame& f : d.videos[0].frames) f.root_pose_gt.reset();
  EXPECT_FALSE(InitialRootPoseErrors(d).has_value());
}

}  // namespace
}  // namespace banmo
