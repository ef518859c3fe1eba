// Unit tests of automatic model sizing (optim/auto_size.h): the bone split
// (moments, sizes, warp change, determinism), the error attribution, the
// widening of the canonical field (function preserved) and one grow step
// on the tiny scene.
#include "banmo/optim/auto_size.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "banmo/deform/bones.h"
#include "banmo/field/mlp_widen.h"
#include "banmo/optim/solver.h"
#include "tiny_solver_scene.h"

namespace banmo {
namespace {

Eigen::Matrix3d Covariance(const double* bone) {
  const Eigen::Quaterniond q(bone[kBoneQw], bone[kBoneQw + 1], bone[kBoneQw + 2],
                             bone[kBoneQw + 3]);
  const Eigen::Matrix3d r = q.normalized().toRotationMatrix();
  Eigen::Vector3d var;
  for (int k = 0; k < 3; ++k) var[k] = std::exp(2.0 * bone[kBoneLogScale + k]);
  return r * var.asDiagonal() * r.transpose();
}

// An anisotropic, rotated bone.
std::vector<double> SomeBone() {
  std::vector<double> bone(kBoneSize);
  bone[0] = 0.1, bone[1] = -0.2, bone[2] = 0.3;
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, -1).normalized()));
  bone[kBoneQw] = q.w(), bone[kBoneQw + 1] = q.x(), bone[kBoneQw + 2] = q.y();
  bone[kBoneQw + 3] = q.z();
  bone[kBoneLogScale] = std::log(0.3), bone[kBoneLogScale + 1] = std::log(0.1);
  bone[kBoneLogScale + 2] = std::log(0.15);
  return bone;
}

// The two copies form a mixture with the bone's mean and covariance, for
// any direction (1e-12: closed-form algebra on O(0.1) numbers).
TEST(SplitBoneGeometry, CopiesMatchTheBonesMoments) {
  const std::vector<double> bone = SomeBone();
  const Eigen::Matrix3d s = Covariance(bone.data());
  for (const Eigen::Vector3d& dir :
       {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0.3, -1, 0.2), Eigen::Vector3d(0, 0, 1)}) {
    for (double a : kSplitOffsets) {
      std::vector<double> first(kBoneSize), second(kBoneSize);
      SplitBoneGeometry(bone.data(), dir, a, first.data(), second.data());
      const Eigen::Vector3d c0(bone[0], bone[1], bone[2]);
      const Eigen::Vector3d c1(first[0], first[1], first[2]);
      const Eigen::Vector3d c2(second[0], second[1], second[2]);
      EXPECT_LT((0.5 * (c1 + c2) - c0).norm(), 1e-12);
      // Offset along the direction.
      EXPECT_LT((c2 - c1).normalized().cross(dir.normalized()).norm(), 1e-9);
      const Eigen::Matrix3d s1 = Covariance(first.data());
      EXPECT_LT((s1 - Covariance(second.data())).norm(), 1e-12);
      const Eigen::Matrix3d mixture = s1 + 0.25 * (c2 - c1) * (c2 - c1).transpose();
      EXPECT_LT((mixture - s).norm(), 1e-12) << "a " << a;
      // The copies are smaller along the split direction.
      const Eigen::Vector3d u = dir.normalized();
      EXPECT_LT(u.dot(s1 * u), u.dot(s * u));
    }
  }
  // a = sqrt(3)/2 along a principal axis halves the scale on that axis.
  const Eigen::Quaterniond q(bone[kBoneQw], bone[kBoneQw + 1], bone[kBoneQw + 2],
                             bone[kBoneQw + 3]);
  const Eigen::Vector3d axis = q.toRotationMatrix().col(0);
  std::vector<double> first(kBoneSize), second(kBoneSize);
  SplitBoneGeometry(bone.data(), axis, kSplitOffsets[4], first.data(), second.data());
  EXPECT_NEAR(axis.dot(Covariance(first.data()) * axis), 0.25 * 0.3 * 0.3, 1e-12);
}

// A small model with non-trivial bone transforms, and surface-like points:
// canonical points around the bones, posed by the forward warp.
struct PosedScene {
  std::unique_ptr<Model> model;
  std::vector<SurfacePoint> points;
  double mean_motion = 0.0;  // mean |forward warp(X) - X|
};

PosedScene MakePosedScene(int num_bones) {
  PosedScene scene;
  ModelOptions options = testing::TinySolverConfig(StepRule::kAdam, 1).model;
  options.num_bones = num_bones;
  PinholeCamera camera;
  camera.width = camera.height = 32;
  camera.intrinsics << 40, 40, 16, 16;
  scene.model = std::make_unique<Model>(options, std::vector<int>{3, 2},
                                        std::vector<PinholeCamera>{camera, camera});
  Model& m = *scene.model;
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int v = 0; v < m.num_videos(); ++v) {
    for (FrameParameters& f : m.video(v).frames) {
      for (int b = 0; b < num_bones; ++b) {
        double* pose = f.bones_t.data() + kPoseSize * b;
        const Eigen::Quaterniond q(
            Eigen::AngleAxisd(0.4 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()));
        pose[0] = q.w(), pose[1] = q.x(), pose[2] = q.y(), pose[3] = q.z();
        for (int k = 0; k < 3; ++k) pose[4 + k] = 0.1 * u(rng);
      }
    }
  }
  const BoneSet bones = BoneSet::Of(m);
  for (int i = 0; i < 400; ++i) {
    SurfacePoint p;
    p.video = i % 2;
    p.frame = (i / 2) % (p.video == 0 ? 3 : 2);
    const int b = i % num_bones;
    p.canonical = Eigen::Vector3d(m.bones()[kBoneSize * b], m.bones()[kBoneSize * b + 1],
                                  m.bones()[kBoneSize * b + 2]) +
                  0.15 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const double* t = m.frame(p.video, p.frame).bones_t.data();
    ForwardWarp(num_bones, m.bones(), t, p.canonical.data(), p.posed.data());
    scene.mean_motion += (p.posed - p.canonical).norm() / 400;
    p.opacity = 1.0;
    p.error = 1.0;
    p.attribution.assign(num_bones, 1.0 / num_bones);
    scene.points.push_back(p);
  }
  return scene;
}

TEST(SplitBones, SizesTransformsAndDeterminism) {
  const PosedScene scene = MakePosedScene(4);
  const BoneSet before = BoneSet::Of(*scene.model);
  const std::vector<BoneSplit> splits = {{2, Eigen::Vector3d(1, 0, 0), 0.7},
                                         {0, Eigen::Vector3d(0, 1, 1), 0.5}};
  std::vector<int> new_to_old;
  const BoneSet after = SplitBones(before, splits, &new_to_old);
  EXPECT_EQ(after.num_bones, 6);
  EXPECT_EQ(after.bones.size(), 6u * kBoneSize);
  EXPECT_EQ(new_to_old, (std::vector<int>{0, 1, 2, 3, 2, 0}));
  for (size_t v = 0; v < after.bones_t.size(); ++v) {
    for (size_t t = 0; t < after.bones_t[v].size(); ++t) {
      const std::vector<double>& f = after.bones_t[v][t];
      ASSERT_EQ(f.size(), 6u * kPoseSize);
      for (int b = 0; b < 6; ++b) {
        EXPECT_EQ(0, std::memcmp(f.data() + kPoseSize * b,
                                 before.bones_t[v][t].data() + kPoseSize * new_to_old[b],
                                 sizeof(double) * kPoseSize));
      }
    }
  }
  // Untouched bones are unchanged.
  for (int b : {1, 3}) {
    EXPECT_EQ(0, std::memcmp(after.bones.data() + kBoneSize * b,
                             before.bones.data() + kBoneSize * b, sizeof(double) * kBoneSize));
  }
  const BoneSet again = SplitBones(before, splits);
  EXPECT_EQ(again.bones, after.bones);

  // Written into the model: sizes follow.
  Model& m = *scene.model;
  after.WriteTo(&m);
  EXPECT_EQ(m.num_bones(), 6);
  EXPECT_EQ(m.options().num_bones, 6);
  EXPECT_EQ(m.bones_size(), 6 * kBoneSize);
  EXPECT_EQ(m.frame(1, 1).bones_t.size(), 6u * kPoseSize);
}

// The split changes the warps little compared with the motion they
// describe: one bone split with the offset the grow step would choose
// moves the warped surface points by a small fraction of the warp's own
// displacement (measured: mean 1.5-3.6 % of the mean displacement, max
// 15-26 % of it; 10 % and 50 % asserted).
TEST(SplitBones, WarpChangeIsSmall) {
  const PosedScene scene = MakePosedScene(4);
  const BoneSet before = BoneSet::Of(*scene.model);
  for (int b = 0; b < 4; ++b) {
    double best = 1e300;
    WarpChange best_change;
    for (double a : kSplitOffsets) {
      const WarpChange c = MeasureWarpChange(
          before, SplitBones(before, {{b, Eigen::Vector3d(1, 0.5, 0), a}}), scene.points);
      if (c.mean_backward + c.mean_forward < best) {
        best = c.mean_backward + c.mean_forward;
        best_change = c;
      }
    }
    SCOPED_TRACE(::testing::Message() << "bone " << b << " motion " << scene.mean_motion);
    EXPECT_EQ(best_change.points, 400);
    EXPECT_LT(best_change.mean_forward, 0.1 * scene.mean_motion);
    EXPECT_LT(best_change.mean_backward, 0.1 * scene.mean_motion);
    EXPECT_LT(best_change.max_forward, 0.5 * scene.mean_motion);
  }
  // With identity transforms every warp is the identity: no change at all.
  BoneSet rest = before;
  for (auto& video : rest.bones_t) {
    for (auto& f : video) {
      for (int b = 0; b < 4; ++b) PoseSetIdentity(f.data() + kPoseSize * b);
    }
  }
  const WarpChange none =
      MeasureWarpChange(rest, SplitBones(rest, {{1, Eigen::Vector3d(0, 0, 1), 0.7}}), scene.points);
  EXPECT_LT(none.max_forward, 1e-12);
  EXPECT_LT(none.max_backward, 1e-12);
}

TEST(AttributeErrors, SharesAndRatios) {
  // Three bones; rays of bone 2 carry 4x the error of the others.
  std::vector<SurfacePoint> points;
  for (int i = 0; i < 300; ++i) {
    SurfacePoint p;
    p.attribution.assign(3, 0.0);
    p.attribution[i % 3] = 0.8;
    p.attribution[(i + 1) % 3] = 0.2;
    p.error = (i % 3 == 2) ? 4.0 : 1.0;
    points.push_back(p);
  }
  const BoneAttribution a = AttributeErrors(points, 3);
  double mass = 0.0, error = 0.0;
  for (int b = 0; b < 3; ++b) {
    mass += a.mass_share[b];
    error += a.error_share[b];
    EXPECT_NEAR(a.ratio[b], a.error_share[b] / a.mass_share[b], 1e-15);
  }
  EXPECT_NEAR(mass, 1.0, 1e-12);
  EXPECT_NEAR(error, 1.0, 1e-12);
  EXPECT_NEAR(a.mean_error, 2.0, 1e-12);
  // Bone 2: mass 1/3, error (0.8 * 4 + 0.2 * 1) / 6 = 0.5667 -> ratio 1.7.
  EXPECT_NEAR(a.ratio[2], 1.7, 1e-12);
  EXPECT_LT(a.ratio[0], 1.0);
  EXPECT_LT(a.ratio[1], 1.0);
}

// Widening the canonical field with exact Net2WiderNet (no noise) keeps
// sdf, feature and rgb (1e-12, as tests/field/mlp_widen_test.cc) and gives
// blocks of the new widths.
TEST(ModelSetFieldWidths, ExactWideningPreservesTheField) {
  ModelOptions options = testing::TinySolverConfig(StepRule::kAdam, 1).model;
  PinholeCamera camera;
  camera.width = camera.height = 32;
  camera.intrinsics << 40, 40, 16, 16;
  Model m(options, {2}, {camera});
  // Annealing state is carried over.
  m.SetFieldAnnealing(2.5);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  FieldBatch batch;
  batch.x.resize(3, 50);
  batch.view_dir.resize(3, 50);
  batch.appearance.resize(options.field.appearance_code_dim, 50);
  for (int j = 0; j < 50; ++j) {
    batch.x.col(j) = Eigen::Vector3d(u(rng), u(rng), u(rng));
    batch.view_dir.col(j) = Eigen::Vector3d(u(rng), u(rng), 1.0).normalized();
    for (int a = 0; a < batch.appearance.rows(); ++a) batch.appearance(a, j) = u(rng);
  }
  m.field().ForwardBatch(m.sdf(), m.color(), &batch, false);
  const Eigen::VectorXd sdf = batch.sdf;
  const Eigen::Matrix3Xd rgb = batch.rgb;
  const Eigen::MatrixXd feature = batch.feature;
  MlpWidening s = WidenMlp(m.field().sdf_mlp(), m.sdf(), 48, 0.0, &rng);
  MlpWidening c = WidenMlp(m.field().color_mlp(), m.color(), 24, 0.0, &rng);
  m.SetFieldWidths(48, 24, s.params, c.params);
  EXPECT_EQ(m.options().field.sdf_width, 48);
  EXPECT_EQ(m.options().field.color_width, 24);
  EXPECT_EQ(m.field().sdf_mlp().options().width, 48);
  EXPECT_EQ(m.sdf_size(), m.field().SdfParameterSize());
  EXPECT_EQ(m.color_size(), m.field().ColorParameterSize());
  EXPECT_EQ(m.field().position_encoding().annealing_alpha(), 2.5);
  m.field().ForwardBatch(m.sdf(), m.color(), &batch, false);
  EXPECT_LT((batch.sdf - sdf).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((batch.feature - feature).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((batch.rgb - rgb).cwiseAbs().maxCoeff(), 1e-12);
}

// One grow step on the tiny scene after a few batches: with error_ratio 1
// some bone is always above the ratio, so bones are split; the warps move
// little; the same generator state gives the same model bit for bit.
TEST(AutoSizeGrow, SplitsBonesDeterministically) {
  const Dataset& data = testing::TinyQuadrupedDataset();
  SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 15);
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  SolveOptions quiet;
  quiet.quiet = true;
  solver.Run(quiet);

  AutoSizeOptions options;
  options.enabled = true;
  options.error_ratio = 1.0;
  options.max_bones = 6;
  options.eval_rays = 512;
  const RaySampler sampler(data);
  std::vector<std::vector<double>> results;
  for (int run = 0; run < 2; ++run) {
    std::unique_ptr<Model> model = MakeModelForDataset(data, config.model);
    const std::vector<double> trained = testing::AllParameters(solver.model());
    const double* p = trained.data();
    model->ForEachBlock([&](const std::string&, double* d, int n) {
      std::copy(p, p + n, d);
      p += n;
    });
    std::mt19937 rng(123);
    AutoSizeRemaps remaps;
    const AutoSizeEvent e = AutoSizeGrow(options, sampler, config.stages[0].sampling, 16,
                                         solver.canonical_bounds(), &rng, model.get(), &remaps);
    EXPECT_EQ(e.bones_before, 4);
    EXPECT_GT(e.bones_after, 4);
    EXPECT_LE(e.bones_after, 6);
    EXPECT_EQ(model->num_bones(), e.bones_after);
    EXPECT_EQ(static_cast<int>(e.splits.size()), e.bones_after - 4);
    EXPECT_EQ(e.rays, 512);
    EXPECT_GT(e.object_rays, 100);  // about half the rays are drawn inside the mask
    EXPECT_LE(e.object_rays, e.rays);
    EXPECT_GT(e.mean_error, 0.0);
    EXPECT_GE(e.split_ratios[0], 1.0);
    EXPECT_GT(e.warp.points, 0);
    // Warp change in canonical units (object half-extent ~1): measured
    // mean 6e-4, max 5e-3; a split that moved the surface visibly would be
    // > 0.05.
    EXPECT_LT(e.warp.mean_forward, 0.02);
    EXPECT_LT(e.warp.mean_backward, 0.02);
    ASSERT_NE(remaps.For("bones"), nullptr);
    ASSERT_NE(remaps.For("video1/frame3/bones_t"), nullptr);
    EXPECT_EQ(remaps.For("video1/frame3/bones_t")->source.size(), 6u * e.bones_after);
    EXPECT_EQ(remaps.For("sdf"), nullptr);
    EXPECT_FALSE(e.Describe().empty());
    results.push_back(testing::AllParameters(*model));
  }
  ASSERT_EQ(results[0].size(), results[1].size());
  EXPECT_EQ(0,
            std::memcmp(results[0].data(), results[1].data(), sizeof(double) * results[0].size()));
}

// At max_bones, a grow step widens the SDF and colour MLPs instead; the
// field barely changes (only the symmetry-breaking noise moves it).
TEST(AutoSizeGrow, WidensWhenNoBoneIsSplit) {
  const Dataset& data = testing::TinyQuadrupedDataset();
  SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 1);
  std::unique_ptr<Model> model = MakeModelForDataset(data, config.model);
  AutoSizeOptions options;
  options.enabled = true;
  options.max_bones = config.model.num_bones;
  options.max_width = 64;
  options.eval_rays = 256;
  const RaySampler sampler(data);
  std::mt19937 rng(5);
  AutoSizeRemaps remaps;
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d::Constant(-1.2), Eigen::Vector3d::Constant(1.2));
  const AutoSizeEvent e = AutoSizeGrow(options, sampler, config.stages[0].sampling, 16, bounds,
                                       &rng, model.get(), &remaps);
  EXPECT_TRUE(e.splits.empty());
  EXPECT_EQ(e.sdf_width_before, 32);
  EXPECT_EQ(e.sdf_width_after, 64);
  EXPECT_EQ(e.color_width_before, 16);
  EXPECT_EQ(e.color_width_after, 32);
  EXPECT_EQ(model->options().field.sdf_width, 64);
  EXPECT_EQ(model->sdf_size(), model->field().SdfParameterSize());
  EXPECT_LT(e.sdf_change_max, 0.01);  // measured 2e-3 (mean 7e-4)
  ASSERT_NE(remaps.For("sdf"), nullptr);
  EXPECT_EQ(static_cast<int>(remaps.For("sdf")->source.size()), model->sdf_size());
  EXPECT_EQ(remaps.For("bones"), nullptr);
  // Doubling is capped at max_width: the SDF stays, the colour MLP grows.
  const AutoSizeEvent next = AutoSizeGrow(options, sampler, config.stages[0].sampling, 16, bounds,
                                          &rng, model.get(), &remaps);
  EXPECT_EQ(next.sdf_width_after, 64);
  EXPECT_EQ(next.color_width_after, 64);
  // At max_width: nothing grows.
  const AutoSizeEvent none = AutoSizeGrow(options, sampler, config.stages[0].sampling, 16, bounds,
                                          &rng, model.get(), &remaps);
  EXPECT_FALSE(none.grew());
  EXPECT_TRUE(remaps.by_group.empty());
}

TEST(TangentRemap, CarriesMoments) {
  TangentRemap r;
  r.source = {0, 2, 2, 1};
  r.scale = {1.0, 0.5, 0.5, 1.0};
  std::vector<double> m = {1, 2, 4}, v = {1, 2, 4};
  r.Apply(&m, &v);
  EXPECT_EQ(m, (std::vector<double>{1, 2, 2, 2}));
  EXPECT_EQ(v, (std::vector<double>{1, 1, 1, 2}));
  std::vector<double> empty_m, empty_v;
  r.Apply(&empty_m, &empty_v);
  EXPECT_TRUE(empty_m.empty());
}

}  // namespace
}  // namespace banmo
