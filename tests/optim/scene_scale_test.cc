// Scene-scale normalisation (docs/solver.md, "Scene scale"): the estimate on
// hand-made masks and on synthetic scenes of three object scales, root poses
// in model units, retargeting across scales, the checkpoint key, and short
// solves of a tiny and a huge object whose meshes come out in dataset units
// at the ground truth's size.
#include "banmo/model/scene_scale.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <list>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "banmo/extract/extract.h"
#include "banmo/geometry/mesh_io.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/solver.h"
#include "banmo/util/error.h"
#include "tiny_solver_scene.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

// An object box of w x h pixels with its top-left pixel at (x, y), root depth z.
struct Box {
  int x, y, w, h;
  double z;
};

// One video of 40 x 40 px with fx = 20, fy = 40, one frame per box. Pixels
// around each box are kMaskIgnore (not object pixels: they must not count).
Dataset BoxDataset(const std::vector<Box>& boxes) {
  Dataset d;
  d.videos.resize(1);
  Video& v = d.videos[0];
  v.name = "boxes";
  v.camera.width = v.camera.height = 40;
  v.camera.intrinsics = Eigen::Vector4d(20, 40, 20, 20);
  for (const Box& b : boxes) {
    Frame f;
    f.index = static_cast<int>(v.frames.size());
    f.mask = cv::Mat(40, 40, CV_8UC1, cv::Scalar(kMaskBackground));
    if (b.w > 0) {
      const cv::Rect ignore = cv::Rect(b.x - 1, b.y - 1, b.w + 2, b.h + 2) & cv::Rect(0, 0, 40, 40);
      f.mask(ignore).setTo(kMaskIgnore);
      f.mask(cv::Rect(b.x, b.y, b.w, b.h)).setTo(kMaskObject);
    }
    f.root_pose_init =
        PoseFromAngleAxis(Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(0, 0, b.z));
    v.frames.push_back(f);
  }
  return d;
}

// A 12 x 32 px box is (0.6, 0.8) focal lengths: diagonal 1, size z / 2.
Box UnitDiagonalBox(double z) { return Box{4, 4, 12, 32, z}; }

TEST(EstimateSceneScale, NinetiethPercentileOfHandMadeFrames) {
  // Sizes 0.1, 0.2, ..., 1.1 in shuffled order: the 90th percentile (rank
  // 0.9 * 10 = 9 of 0..10) is 1.0.
  std::vector<Box> boxes;
  for (int k : {7, 2, 11, 5, 1, 9, 4, 10, 3, 8, 6}) boxes.push_back(UnitDiagonalBox(0.2 * k));
  SceneScaleEstimate e = EstimateSceneScale(BoxDataset(boxes));
  // Tolerance: a few roundings of the box diagonal (0.6^2 + 0.8^2 in double).
  EXPECT_NEAR(e.estimate, 1.0, 1e-12);
  EXPECT_EQ(e.scale, 1.0);
  EXPECT_EQ(e.frames_used, 11);
  EXPECT_EQ(e.frames_border, 0);

  // Not counted: a clipped object (touches the border) however large, an
  // empty mask, a skipped frame, a root behind the camera.
  boxes.push_back(Box{0, 4, 12, 32, 100.0});
  boxes.push_back(Box{0, 0, 0, 0, 1.0});
  boxes.push_back(UnitDiagonalBox(50.0));
  boxes.push_back(UnitDiagonalBox(-3.0));
  Dataset d = BoxDataset(boxes);
  d.videos[0].frames[13].skip = true;
  e = EstimateSceneScale(d);
  EXPECT_NEAR(e.estimate, 1.0, 1e-12);
  EXPECT_EQ(e.frames_used, 11);
  EXPECT_EQ(e.frames_border, 1);
  EXPECT_FALSE(e.border_used);

  // Every object clipped: all of them are used.
  e = EstimateSceneScale(BoxDataset({Box{28, 4, 12, 32, 4.0}, Box{28, 8, 12, 32, 2.0}}));
  EXPECT_TRUE(e.border_used);
  EXPECT_EQ(e.frames_used, 2);
  EXPECT_NEAR(e.estimate, 1.0 + 0.9 * (2.0 - 1.0), 1e-12);
  EXPECT_EQ(e.scale, 2.0);

  // Nothing to measure: s = 1.
  e = EstimateSceneScale(BoxDataset({Box{0, 0, 0, 0, 1.0}}));
  EXPECT_EQ(e.frames_used, 0);
  EXPECT_EQ(e.scale, 1.0);
}

TEST(EstimateSceneScale, RoundsToTheNearestPowerOfTwoInLogScale) {
  struct Case {
    double size;  // the object's estimated half-extent
    double scale;
  };
  // log2(0.70) = -0.51 -> -1, log2(0.72) = -0.47 -> 0, log2(1.40) = 0.49 -> 0,
  // log2(1.42) = 0.506 -> 1, log2(0.01) = -6.64 -> -7, log2(100) = 6.64 -> 7.
  for (const Case& c : std::vector<Case>{
           {0.70, 0.5}, {0.72, 1.0}, {1.40, 1.0}, {1.42, 2.0}, {0.01, 1.0 / 128}, {100.0, 128.0}}) {
    const SceneScaleEstimate e = EstimateSceneScale(BoxDataset({UnitDiagonalBox(2 * c.size)}));
    EXPECT_EQ(e.scale, c.scale) << c.size;
  }
}

// The synthetic quadruped at object scales 0.01, 1 and 100: the images are
// the same, every length is scaled, so the estimate scales exactly and s is
// the expected power of two (1 for the unit-sized scene).
TEST(EstimateSceneScale, SyntheticScenesAtThreeObjectScales) {
  const SceneScaleEstimate unit = EstimateSceneScale(testing::TinyQuadrupedScene(1, 1.0).dataset);
  EXPECT_EQ(unit.scale, 1.0);
  EXPECT_EQ(unit.frames_used, 12);
  // The root frame has largest half-extent 1: the estimate is a half-extent
  // seen along the image diagonal (measured 1.12: 0.01 x 1.12 rounds to
  // 2^-6, 100 x 1.12 to 2^7).
  EXPECT_GT(unit.estimate, 0.75);
  EXPECT_LT(unit.estimate, 1.4);
  struct Case {
    double object_scale;
    double expected;  // 2^round(log2(object_scale * unit.estimate))
  };
  for (const Case& c : std::vector<Case>{{0.01, 1.0 / 64}, {100.0, 128.0}}) {
    const SceneScaleEstimate e =
        EstimateSceneScale(testing::TinyQuadrupedScene(1, c.object_scale).dataset);
    // Relative 1e-12: the scaled root depths differ from object_scale * z by
    // one rounding each.
    EXPECT_NEAR(e.estimate / (c.object_scale * unit.estimate), 1.0, 1e-12) << c.object_scale;
    EXPECT_EQ(e.scale, std::exp2(std::round(std::log2(c.object_scale * unit.estimate))));
    EXPECT_EQ(e.scale, c.expected) << c.object_scale << ": estimate " << e.estimate;
    EXPECT_EQ(e.frames_used, unit.frames_used);
  }
}

// (model.recentre off: the root frame as it is; with it, below.)
TEST(MakeModelForDataset, RootTranslationsAreInModelUnits) {
  const Dataset& data = testing::TinyQuadrupedScene(1, 0.01).dataset;
  SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 1);
  config.model.recentre = false;
  ASSERT_FALSE(config.model.scene_scale.has_value());  // auto
  EXPECT_EQ(ResolveSceneScale(data, config.model), 1.0 / 64);
  auto check = [&](const Model& model, double s) {
    EXPECT_EQ(model.scene_scale(), s);
    for (int t = 0; t < 6; ++t) {
      const Pose& in_data = data.videos[1].frames[t].root_pose_init;
      const Pose& in_model = model.frame(1, t).root_init;
      for (int k = 0; k < kPoseT; ++k) EXPECT_EQ(in_model[k], in_data[k]);
      // s is a power of two: the division is exact.
      for (int k = kPoseT; k < kPoseSize; ++k) EXPECT_EQ(in_model[k] * s, in_data[k]);
    }
  };
  check(*MakeModelForDataset(data, config.model), 1.0 / 64);
  ModelOptions fixed = config.model;
  fixed.scene_scale = 0.25;  // a number in the config wins over the estimate
  EXPECT_EQ(ResolveSceneScale(data, fixed), 0.25);
  check(*MakeModelForDataset(data, fixed), 0.25);
}

// Retargeting takes the source model's scale: the new videos' root
// translations are re-expressed in the source's model units.
TEST(CopySharedParameters, TargetTakesTheSourceScale) {
  SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 1);
  config.model.recentre = false;
  const std::unique_ptr<Model> source =
      MakeModelForDataset(testing::TinyQuadrupedScene(1, 1.0).dataset, config.model);
  const Dataset& small = testing::TinyQuadrupedScene(7, 0.01).dataset;
  std::unique_ptr<Model> target = MakeModelForDataset(small, config.model);
  ASSERT_EQ(target->scene_scale(), 1.0 / 64);
  CopySharedParameters(*source, target.get(), "source");
  EXPECT_EQ(target->scene_scale(), 1.0);
  for (int t = 0; t < 6; ++t) {
    const Pose& in_data = small.videos[0].frames[t].root_pose_init;
    // Powers of two on the way: exact.
    EXPECT_EQ(target->frame(0, t).root_init, in_data);
    EXPECT_EQ(target->frame(0, t).root_delta, PoseIdentity());
  }
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Checkpoints of the previous format without the key load with s = 1, and
// their model_size errors: tests/model/model_file_test.cc.
TEST(Checkpoint, KeepsTheSceneScale) {
  const SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 1);
  const std::unique_ptr<Model> model =
      MakeModelForDataset(testing::TinyQuadrupedScene(1, 100.0).dataset, config.model);
  ASSERT_EQ(model->scene_scale(), 128.0);
  const std::string dir = ::testing::TempDir() + "/banmo_scene_scale_checkpoint";
  fs::remove_all(dir);
  SaveCheckpoint(dir, *model, CheckpointInfo{0, 0, SolverConfigToYaml(config)});
  const std::string yaml = ReadText(dir + "/model.yaml");
  ASSERT_NE(yaml.find("scene_scale: 128\n"), std::string::npos) << yaml;
  std::unique_ptr<Model> back = LoadCheckpoint(dir);
  EXPECT_EQ(back->scene_scale(), 128.0);
  EXPECT_EQ(testing::AllParameters(*back), testing::AllParameters(*model));

  // A bad value names the file and the key.
  std::string bad = yaml;
  bad.replace(bad.find("scene_scale: 128"), std::string("scene_scale: 128").size(),
              "scene_scale: -2");
  std::ofstream(dir + "/model.yaml") << bad;
  try {
    LoadCheckpoint(dir);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("model.yaml"), std::string::npos) << message;
    EXPECT_NE(message.find("scene_scale"), std::string::npos) << message;
  }
  fs::remove_all(dir);
}

Eigen::AlignedBox3d BoxOf(const TriangleMesh& mesh) {
  Eigen::AlignedBox3d box;
  for (int i = 0; i < mesh.NumVertices(); ++i) box.extend(Eigen::Vector3d(mesh.vertices.col(i)));
  return box;
}

// A tiny (0.01) and a huge (100) object, solved for 40 batches: everything
// stays finite, and the written mesh of a frame is in dataset units, about
// the ground truth's size and in its place. (Without normalisation the tiny
// object's mesh came out empty and the huge one's ~100x too small.)
TEST(SceneScale, TinyAndHugeObjectsGiveMeshesOfTheirSize) {
  for (const double object_scale : {0.01, 100.0}) {
    SCOPED_TRACE("object scale " + std::to_string(object_scale));
    const synth::SynthScene& scene = testing::TinyQuadrupedScene(1, object_scale);
    const SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 40);
    Solver solver(scene.dataset, config, MakeModelForDataset(scene.dataset, config.model));
    SolveOptions options;
    options.quiet = true;
    const SolveResult result = solver.Run(options);
    ASSERT_TRUE(result.stages[0].finite);

    const std::string dir = ::testing::TempDir() + "/banmo_scene_scale_solve";
    fs::remove_all(dir);
    ExtractOptions extract;
    extract.grid.resolution = 32;
    extract.grid.bounds_min = solver.canonical_bounds().min();
    extract.grid.bounds_max = solver.canonical_bounds().max();
    extract.frames = ParseFrameSelection("0:0,1:5", solver.model());
    ASSERT_NO_THROW(WriteExtraction(solver.model(), extract, dir));
    EXPECT_NE(ReadText(dir + "/extract.json").find("\"scene_scale\": "), std::string::npos);
    for (const auto& [v, t] : extract.frames.frames) {
      char name[64];
      std::snprintf(name, sizeof(name), "/frames/video%02d_frame%05d.ply", v, t);
      const TriangleMesh mesh = ReadMesh(dir + name);
      ASSERT_GT(mesh.NumFaces(), 0);
      ASSERT_TRUE(mesh.vertices.allFinite());
      const Eigen::AlignedBox3d got = BoxOf(mesh);
      const Eigen::AlignedBox3d gt = BoxOf(scene.gt_meshes[v][t]);
      // Size within a factor of 2 of the ground truth's (a 40-batch model is
      // coarse; measured ratios 1.11-1.19), centre within one GT diagonal.
      const double ratio = got.diagonal().norm() / gt.diagonal().norm();
      std::printf("object scale %g, s = %g, frame %d:%d: mesh/GT box diagonal %.3f\n", object_scale,
                  solver.model().scene_scale(), v, t, ratio);
      EXPECT_GT(ratio, 0.5) << v << ":" << t;
      EXPECT_LT(ratio, 2.0) << v << ":" << t;
      EXPECT_LT((got.center() - gt.center()).norm(), gt.diagonal().norm()) << v << ":" << t;
    }
    fs::remove_all(dir);
  }
}

// The tiny quadruped (2 videos x 6 frames) with the object's centre at
// `offset` in the root frame (synth::SynthOptions::root_offset).
const synth::SynthScene& OffsetScene(const Eigen::Vector3d& offset) {
  // A list: references to its scenes stay valid as it grows.
  static std::list<std::pair<Eigen::Vector3d, synth::SynthScene>> scenes;
  for (const auto& [o, scene] : scenes) {
    if (o == offset) return scene;
  }
  synth::SynthOptions o;
  o.num_videos = 2;
  o.frames_per_video = 6;
  o.image_size = 48;
  o.flow_gaps = {1, 2};
  o.seed = 1;
  o.root_offset = offset;
  scenes.emplace_back(offset, synth::RenderSyntheticScene(synth::LoadRig("quadruped"), o));
  return scenes.back().second;
}

// The object centre triangulated from the masks: the rest bounding-box centre
// of the quadruped (the root origin of the centred scene) up to the posed
// object's motion, perspective and occlusion; an offset of the root frame
// moves it by the offset (the images are the same), up to the prior towards
// the root origin: about kObjectCentrePrior times the distance (1.4 here),
// measured 0.0020; 0.005 allowed.
TEST(EstimateObjectCentre, FindsTheObjectWhereverTheRootOriginIs) {
  const ObjectCentreEstimate centred =
      EstimateObjectCentre(OffsetScene(Eigen::Vector3d::Zero()).dataset);
  EXPECT_TRUE(centred.triangulated);
  EXPECT_EQ(centred.frames_used, 12);
  EXPECT_GT(centred.baseline_ratio, 0.3);  // two videos on different arcs
  // Within 0.15 of the root origin (half-extent 1; measured below).
  std::printf("centred scene: estimate (%.4f, %.4f, %.4f)\n", centred.centre.x(),
              centred.centre.y(), centred.centre.z());
  EXPECT_LT(centred.centre.norm(), 0.15);
  const Eigen::Vector3d offset(0.4, 0.9, -0.9);
  const ObjectCentreEstimate moved = EstimateObjectCentre(OffsetScene(offset).dataset);
  EXPECT_TRUE(moved.triangulated);
  EXPECT_LT((moved.centre - (centred.centre + offset)).norm(), 0.005);
}

// Cameras on one spot (identity root poses: `banmo prepare` without
// --poses): the rays meet at the camera, so no triangulation; the centre
// stays at the root origin.
TEST(EstimateObjectCentre, CamerasOnOneSpotKeepTheRootOrigin) {
  const ObjectCentreEstimate e = EstimateObjectCentre(
      BoxDataset({Box{4, 4, 12, 12, 3.0}, Box{20, 10, 10, 8, 3.0}, Box{8, 22, 6, 10, 3.0}}));
  EXPECT_EQ(e.frames_used, 3);
  EXPECT_FALSE(e.triangulated);
  EXPECT_EQ(e.baseline_ratio, 0.0);
  EXPECT_EQ(e.centre, Eigen::Vector3d::Zero());
  // No object pixel anywhere: nothing used.
  const ObjectCentreEstimate none = EstimateObjectCentre(BoxDataset({Box{0, 0, 0, 0, 1.0}}));
  EXPECT_EQ(none.frames_used, 0);
  EXPECT_FALSE(none.triangulated);
}

// model.recentre: G0^t = the data's pose * T(c), so the canonical origin
// sits at the object centre; the model of the offset scene then equals the
// centred scene's (same images, root frames differing by the offset) up to
// the prior's pull on the estimate (0.0020 measured, 0.005 allowed), and the
// scene scale no longer depends on where the root origin is.
TEST(MakeModelForDataset, RecentredModelsDoNotDependOnTheRootOrigin) {
  const SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 1);
  ASSERT_TRUE(config.model.recentre);  // the default
  const Eigen::Vector3d offset(0.4, 0.9, -0.9);
  const Dataset& centred_data = OffsetScene(Eigen::Vector3d::Zero()).dataset;
  const Dataset& moved_data = OffsetScene(offset).dataset;
  const std::unique_ptr<Model> centred = MakeModelForDataset(centred_data, config.model);
  const std::unique_ptr<Model> moved = MakeModelForDataset(moved_data, config.model);
  const Eigen::Vector3d c = EstimateObjectCentre(moved_data).centre;
  EXPECT_EQ(moved->scene_scale(), centred->scene_scale());
  EXPECT_LT((moved->canonical_origin() * moved->scene_scale() - c).norm(), 1e-12);
  for (int v = 0; v < 2; ++v) {
    for (int t = 0; t < 6; ++t) {
      const Eigen::Isometry3d g0 = IsometryFromPose(moved->frame(v, t).root_init.data());
      const Eigen::Isometry3d data =
          IsometryFromPose(moved_data.videos[v].frames[t].root_pose_init.data());
      // The canonical origin is the data's point c (model units: / s).
      EXPECT_LT((g0.translation() * moved->scene_scale() - data * c).norm(), 1e-12);
      EXPECT_LT((g0.linear() - data.linear()).cwiseAbs().maxCoeff(), 1e-15);
      const Eigen::Isometry3d g0_centred = IsometryFromPose(centred->frame(v, t).root_init.data());
      EXPECT_LT((g0.translation() - g0_centred.translation()).norm(), 0.005) << v << ":" << t;
    }
  }
  // Without recentring the offset scene's scale comes from the root origin's
  // depth, which the offset changes.
  ModelOptions off = config.model;
  off.recentre = false;
  EXPECT_EQ(MakeModelForDataset(moved_data, off)->canonical_origin(), Eigen::Vector3d::Zero());
}

// Retargeting re-bases the new videos on the source model's canonical
// origin: a retarget of the offset scene onto a model of the same scene
// keeps that model's G0 (both made by recentring: the same origin).
TEST(CopySharedParameters, TargetTakesTheSourceCanonicalOrigin) {
  const SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 1);
  const Dataset& data = OffsetScene(Eigen::Vector3d(0.4, 0.9, -0.9)).dataset;
  const std::unique_ptr<Model> source = MakeModelForDataset(data, config.model);
  ModelOptions plain = config.model;
  plain.recentre = false;  // the target starts in the root frame
  std::unique_ptr<Model> target = MakeModelForDataset(data, plain);
  CopySharedParameters(*source, target.get(), "source");
  EXPECT_EQ(target->canonical_origin(), source->canonical_origin());
  for (int t = 0; t < 6; ++t) {
    const Pose& want = source->frame(1, t).root_init;
    const Pose& got = target->frame(1, t).root_init;
    for (int k = 0; k < kPoseSize; ++k) EXPECT_NEAR(got[k], want[k], 1e-12) << t << " " << k;
  }
}

// The model file keeps the canonical origin; files written before it read
// as zero.
TEST(Checkpoint, KeepsTheCanonicalOrigin) {
  const SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 1);
  const std::unique_ptr<Model> model =
      MakeModelForDataset(OffsetScene(Eigen::Vector3d(0.4, 0.9, -0.9)).dataset, config.model);
  ASSERT_GT(model->canonical_origin().norm(), 1.0);
  const std::string dir = ::testing::TempDir() + "/banmo_canonical_origin_checkpoint";
  fs::remove_all(dir);
  SaveCheckpoint(dir, *model, CheckpointInfo{0, 0, SolverConfigToYaml(config)});
  EXPECT_EQ(LoadCheckpoint(dir)->canonical_origin(), model->canonical_origin());
  std::string yaml = ReadText(dir + "/model.yaml");
  const size_t at = yaml.find("canonical_origin:");
  ASSERT_NE(at, std::string::npos) << yaml;
  yaml.erase(at, yaml.find('\n', at) - at + 1);
  std::ofstream(dir + "/model.yaml") << yaml;
  EXPECT_EQ(LoadCheckpoint(dir)->canonical_origin(), Eigen::Vector3d::Zero());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace banmo
