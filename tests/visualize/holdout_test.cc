// The held-out score (visualize/holdout.h) on a constructed case whose
// held-out frames are known: the tiny model trained on every frame of the
// tiny quadruped scene. Its held-out frames' transforms are replaced by
// wrong ones, then by the interpolation of their neighbours': the score
// must drop with the wrong ones and come back with the interpolation (the
// scene moves smoothly), and the files must say so.
#include "banmo/visualize/holdout.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "banmo/extract/extract.h"
#include "banmo/model/model_file.h"
#include "trained_tiny_model.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing::TinyQuadrupedDataset;
using testing::TrainedTinyModel;

std::unique_ptr<Model> CopyOf(const Model& model, const fs::path& dir) {
  fs::create_directories(dir);
  WriteModelFiles(dir.string(), model);
  return ReadModelFiles(dir.string());
}

RenderSequenceOptions Options(const Model& model) {
  RenderSequenceOptions o;
  SetTrainedSampling(model, &o.frame);
  o.frame.canonical_bounds = CanonicalBoundsFromSurface(model);
  o.mesh_resolution = 0;
  return o;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(HoldoutScore, InterpolatedTransformsPredictTheHeldOutFrames) {
  const fs::path root =
      fs::temp_directory_path() / ("banmo_holdout_test_" + std::to_string(::getpid()));
  fs::remove_all(root);
  Dataset data = TinyQuadrupedDataset();
  const HoldoutPlan plan = MarkHeldOutFrames(3, &data);  // frames 1 and 4 of both videos
  ASSERT_EQ(plan.frames.size(), 4u);
  const Model& trained = TrainedTinyModel();
  const RenderSequenceOptions options = Options(trained);

  // As trained (the model saw these frames): the reference.
  const HoldoutScore seen = ScoreHeldOutFrames(trained, data, plan, options, (root / "a").string());
  EXPECT_EQ(seen.frames, 4);
  EXPECT_GT(seen.mask_iou, 0.5);

  // Wrong root poses: the object moved half its size sideways.
  std::unique_ptr<Model> model = CopyOf(trained, root / "model");
  for (const HeldOutFrame& h : plan.frames) {
    model->frame(h.video, h.frame).root_delta =
        PoseFromAngleAxis(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.5, 0, 0));
  }
  const HoldoutScore wrong = ScoreHeldOutFrames(*model, data, plan, options, (root / "b").string());
  EXPECT_LT(wrong.mask_iou, seen.mask_iou - 0.2);

  // Interpolated from the neighbours. The tiny scene turns by tens of
  // degrees between frames, so the interpolation is not the trained pose;
  // measured: IoU 0.54 against 0.60 as trained.
  InterpolateHeldOutFrames(plan, model.get());
  for (const HeldOutFrame& h : plan.frames) {
    // The neighbours are untouched.
    const Pose n0 = trained.RootPose(h.video, h.before), n1 = model->RootPose(h.video, h.before);
    EXPECT_EQ((n0 - n1).norm(), 0.0);
  }
  const fs::path out = root / "c";
  const HoldoutScore interpolated = ScoreHeldOutFrames(*model, data, plan, options, out.string());
  EXPECT_GT(interpolated.mask_iou, seen.mask_iou - 0.15);
  EXPECT_GT(interpolated.mask_iou, wrong.mask_iou + 0.1);
  EXPECT_TRUE(std::isfinite(interpolated.psnr));
  EXPECT_GT(interpolated.psnr, wrong.psnr);

  // The files: summary.json's keys, one CSV row per held-out frame, panels.
  const std::string json = ReadText(out / "summary.json");
  for (const char* key : {"\"every\": 3", "\"frames\": 4", "\"mask_iou\":", "\"psnr\":"}) {
    EXPECT_NE(json.find(key), std::string::npos) << key << " in\n" << json;
  }
  std::ifstream csv(out / "frames.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "video,frame,before,after,weight,mask_iou,psnr");
  int rows = 0;
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, 4);
  EXPECT_TRUE(fs::exists(out / "frames" / "video01_frame00004.png"));
  fs::remove_all(root);
}

TEST(HoldoutScore, InterpolatesBonesAndTheRootBetweenNeighbours) {
  const fs::path root =
      fs::temp_directory_path() / ("banmo_holdout_interp_" + std::to_string(::getpid()));
  Dataset data = TinyQuadrupedDataset();
  const HoldoutPlan plan = MarkHeldOutFrames(3, &data);
  std::unique_ptr<Model> model = CopyOf(TrainedTinyModel(), root);
  InterpolateHeldOutFrames(plan, model.get());
  for (const HeldOutFrame& h : plan.frames) {
    ASSERT_DOUBLE_EQ(h.w, 0.5);
    // Midway: equal angles to both neighbours, for the root and each bone.
    const Pose p = model->RootPose(h.video, h.frame);
    const Pose a = model->RootPose(h.video, h.before), b = model->RootPose(h.video, h.after);
    EXPECT_NEAR(RotationAngleBetween(p.data(), a.data()), RotationAngleBetween(p.data(), b.data()),
                1e-9);
    EXPECT_NEAR((p.tail<3>() - 0.5 * (a.tail<3>() + b.tail<3>())).norm(), 0.0, 1e-12);
    const std::vector<double>& bp = model->frame(h.video, h.frame).bones_t;
    const std::vector<double>& ba = model->frame(h.video, h.before).bones_t;
    const std::vector<double>& bb = model->frame(h.video, h.after).bones_t;
    ASSERT_EQ(bp.size(), ba.size());
    for (size_t k = 0; k < bp.size(); k += kPoseSize) {
      EXPECT_NEAR(RotationAngleBetween(&bp[k], &ba[k]), RotationAngleBetween(&bp[k], &bb[k]), 1e-9);
      for (int i = kPoseT; i < kPoseSize; ++i) {
        EXPECT_NEAR(bp[k + i], 0.5 * (ba[k + i] + bb[k + i]), 1e-12);
      }
    }
  }
  fs::remove_all(root);
}

}  // namespace
}  // namespace banmo
