// Held-out frames (io/holdout.h): which frames are left out, their
// neighbours, and their initial root poses taken from the neighbours'.
#include "banmo/io/holdout.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "banmo/geometry/se3.h"
#include "banmo/util/error.h"

namespace banmo {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Videos of the given lengths; frame t of each turns by 0.1 t rad about z
// and sits at depth 3 + t.
Dataset Frames(const std::vector<int>& lengths) {
  Dataset d;
  for (int n : lengths) {
    Video& v = d.videos.emplace_back();
    for (int t = 0; t < n; ++t) {
      Frame& f = v.frames.emplace_back();
      f.index = t;
      f.root_pose_init = PoseFromAngleAxis(Eigen::Vector3d(0, 0, 0.1 * t), {0, 0, 3.0 + t});
    }
  }
  return d;
}

TEST(Holdout, EveryNthFrameFromTheMiddleOfEachPeriod) {
  Dataset d = Frames({10, 7});
  const HoldoutPlan plan = MarkHeldOutFrames(3, &d);
  EXPECT_EQ(plan.every, 3);
  // t % 3 == 1: frames 1, 4, 7 of video 0 and 1, 4 of video 1.
  ASSERT_EQ(plan.frames.size(), 5u);
  const int expected[5][3] = {{0, 1, 0}, {0, 4, 3}, {0, 7, 6}, {1, 1, 0}, {1, 4, 3}};
  for (int i = 0; i < 5; ++i) {
    const HeldOutFrame& h = plan.frames[i];
    EXPECT_EQ(h.video, expected[i][0]);
    EXPECT_EQ(h.frame, expected[i][1]);
    EXPECT_EQ(h.before, expected[i][2]);
    EXPECT_EQ(h.after, h.frame + 1);
    EXPECT_DOUBLE_EQ(h.w, 0.5);
    const Frame& f = d.videos[h.video].frames[h.frame];
    EXPECT_TRUE(f.held_out);
    EXPECT_TRUE(f.skip);  // so every loss and registration passes it by
  }
  int marked = 0;
  for (const Video& v : d.videos) {
    for (const Frame& f : v.frames) marked += f.held_out;
  }
  EXPECT_EQ(marked, 5);
}

TEST(Holdout, InitialPoseComesFromTheNeighboursNotTheFrame) {
  Dataset d = Frames({6});
  // The held-out frame's own pose is garbage: it must never be read.
  d.videos[0].frames[2].root_pose_init.setConstant(std::numeric_limits<double>::quiet_NaN());
  d.videos[0].frames[3].skip = true;                  // empty mask: not a neighbour
  const HoldoutPlan plan = MarkHeldOutFrames(4, &d);  // t % 4 == 2: frame 2
  ASSERT_EQ(plan.frames.size(), 1u);
  const HeldOutFrame& h = plan.frames[0];
  EXPECT_EQ(h.before, 1);
  EXPECT_EQ(h.after, 4);  // frame 3 is skipped
  EXPECT_NEAR(h.w, 1.0 / 3.0, 1e-15);
  const Pose& p = d.videos[0].frames[2].root_pose_init;
  // Rotation 0.1 + (0.4 - 0.1) / 3 = 0.2 rad about z, depth 4 + 3 / 3 = 5.
  const Pose truth = PoseFromAngleAxis(Eigen::Vector3d(0, 0, 0.2), {0, 0, 5.0});
  EXPECT_LT(RotationAngleBetween(p.data(), truth.data()), 1e-12);
  EXPECT_NEAR((p.tail<3>() - truth.tail<3>()).norm(), 0.0, 1e-12);
}

TEST(Holdout, AVideosLastFrameTakesItsOnlyNeighbour) {
  Dataset d = Frames({4});
  const HoldoutPlan plan = MarkHeldOutFrames(2, &d);  // frames 1 and 3
  ASSERT_EQ(plan.frames.size(), 2u);
  EXPECT_EQ(plan.frames[1].frame, 3);
  EXPECT_EQ(plan.frames[1].before, 2);
  EXPECT_EQ(plan.frames[1].after, 2);
  EXPECT_EQ(plan.frames[1].w, 0.0);
  const Pose& p = d.videos[0].frames[3].root_pose_init;
  const Pose& q = d.videos[0].frames[2].root_pose_init;
  EXPECT_LT(RotationAngleBetween(p.data(), q.data()), 1e-12);
}

TEST(Holdout, SkippedFramesAreNeitherHeldOutNorNeighbours) {
  Dataset d = Frames({3, 3});
  d.videos[0].frames[1].skip = true;  // would be held out: already skipped
  d.videos[1].frames[0].skip = true;  // video 1: frame 1's neighbours are 0
  d.videos[1].frames[2].skip = true;  // and 2, both skipped: not held out
  const HoldoutPlan plan = MarkHeldOutFrames(2, &d);
  EXPECT_TRUE(plan.frames.empty());
  EXPECT_FALSE(d.videos[0].frames[1].held_out);
  EXPECT_FALSE(d.videos[1].frames[1].held_out);
  EXPECT_FALSE(d.videos[1].frames[1].skip);
}

TEST(Holdout, ZeroMarksNothingAndOneIsRefused) {
  Dataset d = Frames({5});
  EXPECT_TRUE(MarkHeldOutFrames(0, &d).frames.empty());
  for (const Frame& f : d.videos[0].frames) EXPECT_FALSE(f.skip);
  try {
    MarkHeldOutFrames(1, &d);
    FAIL() << "every = 1 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--holdout-every"), std::string::npos) << e.what();
  }
}

TEST(PoseInterpolate, EndsMidpointAndTheShorterArc) {
  const Pose a = PoseFromAngleAxis(Eigen::Vector3d(0.3, 0, 0), {1, 2, 3});
  const Pose b = PoseFromAngleAxis(Eigen::Vector3d(0, 0.9, 0), {3, 2, 1});
  EXPECT_LT(RotationAngleBetween(PoseInterpolate(a, b, 0.0).data(), a.data()), 1e-12);
  EXPECT_LT(RotationAngleBetween(PoseInterpolate(a, b, 1.0).data(), b.data()), 1e-7);
  const Pose m = PoseInterpolate(a, b, 0.5);
  const double whole = RotationAngleBetween(a.data(), b.data());
  EXPECT_NEAR(RotationAngleBetween(a.data(), m.data()), whole / 2, 1e-12);
  EXPECT_NEAR(RotationAngleBetween(m.data(), b.data()), whole / 2, 1e-12);
  EXPECT_NEAR((m.tail<3>() - Eigen::Vector3d(2, 2, 2)).norm(), 0.0, 1e-15);
  // -q is the same rotation: the interpolation takes the shorter arc.
  Pose b_flipped = b;
  b_flipped.head<4>() *= -1.0;
  const Pose m2 = PoseInterpolate(a, b_flipped, 0.5);
  EXPECT_LT(RotationAngleBetween(m.data(), m2.data()), 1e-12);
  EXPECT_LT(whole, kPi);
}

}  // namespace
}  // namespace banmo
