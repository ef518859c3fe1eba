#include "banmo/model/model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "banmo/util/error.h"

namespace banmo {
namespace {

ModelOptions TinyOptions() {
  ModelOptions o;
  o.num_bones = 4;
  o.field.position_encoding.num_bands = 2;
  o.field.sdf_width = 8;
  o.field.sdf_layers = 2;
  o.field.geometry_feature_dim = 4;
  o.field.color_width = 8;
  o.field.color_layers = 1;
  o.field.embedding_width = 8;
  o.field.embedding_layers = 1;
  o.field.appearance_code_dim = 3;
  return o;
}

Model TinyModel(const ModelOptions& options) {
  PinholeCamera camera;
  camera.width = 16;
  camera.height = 12;
  camera.intrinsics = Eigen::Vector4d(20, 20, 8, 6);
  return Model(options, {2, 1}, {camera, camera});
}

// Model::BlockGroup: the group of every block ForEachBlock names is the one
// its data has (the blocks by accessor, as optim/stage_problem.cc groups
// them); root_init (data, not a parameter) has none.
TEST(Model, BlockGroupOfEveryBlock) {
  ModelOptions options = TinyOptions();
  options.delta_skinning.enabled = true;
  Model model = TinyModel(options);
  using G = ParameterGroup;
  std::map<const double*, G> group_of = {{model.sdf(), G::kSdf},
                                         {model.color(), G::kColor},
                                         {model.embedding(), G::kEmbedding},
                                         {model.log_beta(), G::kLogBeta},
                                         {model.bones(), G::kBones},
                                         {model.delta_skinning_params(), G::kDeltaSkinning},
                                         {model.rest_pose_code(), G::kDeltaSkinning}};
  for (int v = 0; v < model.num_videos(); ++v) {
    group_of[model.video(v).intrinsics.data()] = G::kIntrinsics;
    group_of[model.video(v).appearance.data()] = G::kAppearance;
    for (size_t t = 0; t < model.video(v).frames.size(); ++t) {
      FrameParameters& f = model.frame(v, t);
      group_of[f.root_delta.data()] = G::kRoot;
      group_of[f.bones_t.data()] = G::kBonesT;
      group_of[f.pose_code.data()] = G::kPoseCode;
    }
  }
  int grouped = 0;
  model.ForEachBlock([&](const std::string& name, double* data, int) {
    const std::optional<G> group = Model::BlockGroup(name);
    const auto expected = group_of.find(data);
    if (expected == group_of.end()) {
      EXPECT_FALSE(group.has_value()) << name;  // root_init
      return;
    }
    ASSERT_TRUE(group.has_value()) << name;
    EXPECT_EQ(*group, expected->second) << name;
    ++grouped;
  });
  EXPECT_EQ(grouped, static_cast<int>(group_of.size()));
  EXPECT_FALSE(Model::BlockGroup("video0/frame1/unknown").has_value());
}

TEST(Model, StartsAtIdentityTransformsWithBonesInsideTheSphere) {
  const ModelOptions options = TinyOptions();
  Model model = TinyModel(options);
  EXPECT_EQ(model.num_videos(), 2);
  EXPECT_EQ(model.bones_size(), kBoneSize * 4);
  EXPECT_EQ(model.scene_scale(), 1.0);  // options.scene_scale is auto
  EXPECT_DOUBLE_EQ(std::exp(*model.log_beta()), options.init_beta);
  for (int b = 0; b < 4; ++b) {
    const Eigen::Map<const Eigen::Vector3d> centre(model.bones() + kBoneSize * b + kBoneCenter);
    // On a sphere of half the initial SDF radius.
    EXPECT_NEAR(centre.norm(), 0.5 * options.field.init_sphere_radius, 1e-12) << b;
  }
  for (int v = 0; v < 2; ++v) {
    EXPECT_EQ(model.video(v).appearance.size(), 3u);
    EXPECT_EQ(model.video(v).intrinsics, Eigen::Vector4d(20, 20, 8, 6));
    for (const FrameParameters& f : model.video(v).frames) {
      ASSERT_EQ(f.bones_t.size(), static_cast<size_t>(kPoseSize * 4));
      for (int b = 0; b < 4; ++b) {
        Pose identity = PoseIdentity();
        EXPECT_EQ(Eigen::Map<const Pose>(f.bones_t.data() + kPoseSize * b), identity);
      }
      EXPECT_TRUE(f.pose_code.empty());
    }
  }
  EXPECT_FALSE(model.has_delta_skinning());
  EXPECT_FALSE(model.canonical_bounds().has_value());
  EXPECT_FALSE(model.training_sampling().has_value());
}

TEST(Model, ForEachBlockVisitsEveryBlockOnceInTheDocumentedOrder) {
  Model model = TinyModel(TinyOptions());
  std::vector<std::string> names;
  std::set<const double*> seen;
  int total = 0;
  model.ForEachBlock([&](const std::string& name, double* data, int size) {
    names.push_back(name);
    EXPECT_TRUE(seen.insert(data).second) << name;
    total += size;
  });
  const std::vector<std::string> expected = {
      "sdf",
      "color",
      "embedding",
      "log_beta",
      "bones",
      "video0/intrinsics",
      "video0/appearance",
      "video0/frame0/root_delta",
      "video0/frame0/root_init",
      "video0/frame0/bones_t",
      "video0/frame1/root_delta",
      "video0/frame1/root_init",
      "video0/frame1/bones_t",
      "video1/intrinsics",
      "video1/appearance",
      "video1/frame0/root_delta",
      "video1/frame0/root_init",
      "video1/frame0/bones_t",
  };
  EXPECT_EQ(names, expected);
  // The const overload visits the same blocks.
  const Model& view = model;
  int const_total = 0;
  std::vector<std::string> const_names;
  view.ForEachBlock([&](const std::string& name, const double* data, int size) {
    const_names.push_back(name);
    EXPECT_TRUE(seen.count(data)) << name;
    const_total += size;
  });
  EXPECT_EQ(const_names, expected);
  EXPECT_EQ(const_total, total);
}

TEST(Model, RootPoseComposesInitialPoseAndObjectSideDelta) {
  Model model = TinyModel(TinyOptions());
  FrameParameters& f = model.frame(0, 1);
  // G0: 90 deg about z, translation (1, 0, 0); dG: translation (0, 2, 0) in
  // the root frame, which G0 turns into (-2, 0, 0) in the camera.
  f.root_init = PoseFromAngleAxis(Eigen::Vector3d(0, 0, M_PI / 2), Eigen::Vector3d(1, 0, 0));
  f.root_delta = PoseFromAngleAxis(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 2, 0));
  const Pose g = model.RootPose(0, 1);
  // G = G0 dG: t = t0 + R0 t_delta, R = R0 R_delta (1e-15: one rotation).
  EXPECT_NEAR(g[kPoseT + 0], -1.0, 1e-15);
  EXPECT_NEAR(g[kPoseT + 1], 0.0, 1e-15);
  EXPECT_NEAR(g[kPoseT + 2], 0.0, 1e-15);
  for (int k = 0; k < 4; ++k) EXPECT_EQ(g[kPoseQw + k], f.root_init[kPoseQw + k]);
}

TEST(Model, SetBonesKeepsTheFirstTransformsAndAddsIdentities) {
  Model model = TinyModel(TinyOptions());
  model.frame(0, 0).bones_t[kPoseT] = 0.5;  // bone 0 moved
  std::vector<double> bones(kBoneSize * 6, 0.25);
  model.SetBones(6, bones);
  EXPECT_EQ(model.num_bones(), 6);
  EXPECT_EQ(model.options().num_bones, 6);
  EXPECT_EQ(model.bones()[kBoneSize * 5], 0.25);
  const FrameParameters& f = model.frame(0, 0);
  ASSERT_EQ(f.bones_t.size(), static_cast<size_t>(kPoseSize * 6));
  EXPECT_EQ(f.bones_t[kPoseT], 0.5);
  EXPECT_EQ(Eigen::Map<const Pose>(f.bones_t.data() + kPoseSize * 5), PoseIdentity());
}

TEST(Model, SetFieldWidthsKeepsOptionsInStep) {
  Model model = TinyModel(TinyOptions());
  CanonicalFieldOptions wider = model.options().field;
  wider.sdf_width = 12;
  wider.color_width = 10;
  const CanonicalField field(wider);
  model.SetFieldWidths(12, 10, std::vector<double>(field.SdfParameterSize(), 0.5),
                       std::vector<double>(field.ColorParameterSize(), 0.25));
  EXPECT_EQ(model.options().field.sdf_width, 12);
  EXPECT_EQ(model.options().field.color_width, 10);
  EXPECT_EQ(model.sdf_size(), field.SdfParameterSize());
  EXPECT_EQ(model.color()[0], 0.25);
}

TEST(Model, SceneScaleFromOptionsAndSetter) {
  ModelOptions options = TinyOptions();
  options.scene_scale = 4.0;
  Model model = TinyModel(options);
  EXPECT_EQ(model.scene_scale(), 4.0);
  model.set_scene_scale(0.5);
  EXPECT_EQ(model.scene_scale(), 0.5);
}

TEST(Model, CanonicalBoundsAndTrainingSamplingAreRecorded) {
  Model model = TinyModel(TinyOptions());
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1, -2, -3), Eigen::Vector3d(1, 2, 3));
  model.set_canonical_bounds(box);
  ASSERT_TRUE(model.canonical_bounds().has_value());
  EXPECT_EQ(model.canonical_bounds()->min(), box.min());
  model.set_training_sampling(TrainingSampling{12, 0.3, true});
  ASSERT_TRUE(model.training_sampling().has_value());
  EXPECT_EQ(model.training_sampling()->samples_per_ray, 12);
}

TEST(Model, FieldAnnealingIsSetThroughTheModel) {
  Model model = TinyModel(TinyOptions());
  model.SetFieldAnnealing(1.5);
  EXPECT_EQ(model.field().position_encoding().annealing_alpha(), 1.5);
}

TEST(ModelOptions, CheckNamesTheKey) {
  auto message = [](const ModelOptions& o) -> std::string {
    try {
      o.Check();
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(message(TinyOptions()), "");
  ModelOptions o = TinyOptions();
  o.num_bones = 300;
  EXPECT_NE(message(o).find("model.num_bones"), std::string::npos);
  o = TinyOptions();
  o.init_beta = 0;
  EXPECT_NE(message(o).find("model.init_beta"), std::string::npos);
  o = TinyOptions();
  o.scene_scale = -1.0;
  EXPECT_NE(message(o).find("model.scene_scale"), std::string::npos);
  o = TinyOptions();
  o.auto_size.enabled = true;
  o.delta_skinning.enabled = true;
  EXPECT_NE(message(o).find("model.auto_size.enabled"), std::string::npos);
  o = TinyOptions();
  o.auto_size.grow_at = {0.5, 0.4};
  EXPECT_NE(message(o).find("grow_at[1]"), std::string::npos);
  o = TinyOptions();
  o.num_bones = 0;
  o.delta_skinning.enabled = true;
  EXPECT_NE(message(o).find("model.delta_skinning.enabled"), std::string::npos);
}

}  // namespace
}  // namespace banmo
