#include "banmo/optim/config.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "../common/input_error.h"
#include "banmo/model/model.h"
#include "banmo/optim/load_options.h"
#include "banmo/util/error.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

using testing::ErrorOf;

std::string ParseError(const std::string& yaml) {
  return ErrorOf([&] { ParseSolverConfig(yaml, "test.yaml"); });
}

// The smallest valid config: one stage with the defaults.
const char kMinimal[] = "stages:\n  - {}\n";

// Features are loaded when any stage weights a term that reads them.
TEST(DatasetLoadOptions, FeaturesForEachFeatureTerm) {
  const std::vector<std::string> terms = {"feature_match", "cycle_2d", "feature_render"};
  auto yaml = [&](const std::string& on) {
    std::string y = "stages:\n  - losses: {silhouette: {weight: 1}";
    for (const std::string& t : terms)
      y += ", " + t + ": {weight: " + (t == on ? "0.5" : "0") + "}";
    return y + "}\n";
  };
  for (const std::string& t : terms) {
    EXPECT_TRUE(DatasetLoadOptions(ParseSolverConfig(yaml(t), "test.yaml")).load_features) << t;
  }
  EXPECT_FALSE(DatasetLoadOptions(ParseSolverConfig(yaml(""), "test.yaml")).load_features);
}

TEST(SolverConfig, MinimalConfigTakesStructDefaults) {
  const SolverConfig c = ParseSolverConfig(kMinimal, "test.yaml");
  ASSERT_EQ(c.stages.size(), 1u);
  const StageConfig d;
  EXPECT_EQ(c.stages[0].name, d.name);
  EXPECT_EQ(c.stages[0].batches, d.batches);
  EXPECT_EQ(c.stages[0].constant, d.constant);
  EXPECT_EQ(c.stages[0].sampling.flow_gaps, d.sampling.flow_gaps);
  EXPECT_EQ(c.model.num_bones, ModelOptions().num_bones);
  EXPECT_EQ(c.model.field.position_encoding.num_bands, PositionalEncodingOptions().num_bands);
  EXPECT_EQ(c.seed, 0u);
  // A null stage entry ("- ") is a stage with the defaults too.
  EXPECT_EQ(ParseSolverConfig("stages:\n  -\n", "test.yaml").stages.size(), 1u);
}

TEST(SolverConfig, OldIterationsKeyIsADeprecatedAliasOfBatches) {
  const SolverConfig c = ParseSolverConfig(
      "defaults:\n  iterations: 7\nstages:\n  - {}\n  - iterations: 3\n    batch_rays: 5\n"
      "  - batches: 4\n",
      "test.yaml");
  ASSERT_EQ(c.stages.size(), 3u);
  EXPECT_EQ(c.stages[0].batches, 7);  // from defaults
  EXPECT_EQ(c.stages[1].batches, 3);
  EXPECT_EQ(c.stages[1].batch_rays, 5);  // the other keys of the renamed map
  EXPECT_EQ(c.stages[2].batches, 4);
  // Written back under the new name only.
  const std::string yaml = SolverConfigToYaml(c);
  EXPECT_NE(yaml.find("batches: 3"), std::string::npos);
  EXPECT_EQ(yaml.find("iterations: 3"), std::string::npos);
  // Both names in one stage: an error naming both keys.
  try {
    ParseSolverConfig("stages:\n  - batches: 3\n    iterations: 3\n", "test.yaml");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("'stages[0].iterations'"), std::string::npos) << message;
    EXPECT_NE(message.find("'stages[0].batches'"), std::string::npos) << message;
  }
  // The alias is a stage key only: elsewhere `iterations` stays unknown.
  EXPECT_THROW(ParseSolverConfig("stages:\n  - lm: {iterations: 3}\n", "test.yaml"), InputError);
}

TEST(SolverConfig, EveryProblemFileLoadsAndChecks) {
  const fs::path dir = fs::path(BANMO_SOURCE_DIR) / "problems";
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    names.insert(entry.path().stem().string());
    SolverConfig c;
    EXPECT_NO_THROW(c = LoadSolverConfig(entry.path().string()));
    EXPECT_FALSE(c.stages.empty());
    EXPECT_NO_THROW(CheckSolverConfig(c, entry.path().string()));
    // The resolved form reads back to the same config.
    const std::string yaml = SolverConfigToYaml(c);
    EXPECT_EQ(SolverConfigToYaml(ParseSolverConfig(yaml, "resolved")), yaml);
  }
  for (const char* required : {"default", "fox", "fox_noisy_poses", "rigid", "tiny"}) {
    EXPECT_TRUE(names.count(required)) << "problems/" << required << ".yaml missing";
  }
}

// Each shipped model builds (field MLPs, bones) without tripping a CHECK.
TEST(SolverConfig, ProblemModelsConstruct) {
  for (const auto& entry : fs::directory_iterator(fs::path(BANMO_SOURCE_DIR) / "problems")) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    const SolverConfig c = LoadSolverConfig(entry.path().string());
    PinholeCamera camera;
    camera.width = 64;
    camera.height = 48;
    camera.intrinsics << 60, 60, 32, 24;
    const Model model(c.model, {2}, {camera});
    EXPECT_EQ(model.num_bones(), c.model.num_bones);
    EXPECT_GT(model.sdf_size(), 0);
  }
}

TEST(SolverConfig, ProblemFilesFollowThePaperStages) {
  const SolverConfig c = LoadSolverConfig(std::string(BANMO_SOURCE_DIR) + "/problems/default.yaml");
  ASSERT_EQ(c.stages.size(), 3u);
  // Stage 1: bones re-initialised early (paper) and again once the limbs have formed.
  EXPECT_EQ(c.stages[0].schedule.bone_reinit_at, (std::vector<double>{0.2, 0.5}));
  // Bones registered after the second re-initialisation and again at 75 %.
  EXPECT_EQ(c.stages[0].bone_registration.at, (std::vector<double>{0.5, 0.75}));
  // ... with the mask term (fitted vertices into each frame's silhouette);
  // the coverage term stays off (bird: one seed gains, the other loses).
  EXPECT_EQ(c.stages[0].bone_registration.mask_weight, 10.0);
  EXPECT_EQ(c.stages[0].bone_registration.coverage_weight, 0.0);
  // Stage 2: 2D cycle (and a little silhouette), articulation only.
  const StageConfig& s2 = c.stages[1];
  EXPECT_GT(s2.losses[LossTerm::kCycle2d].weight, 0);
  EXPECT_EQ(s2.losses[LossTerm::kRgb].weight, 0);
  EXPECT_EQ(s2.losses[LossTerm::kFlow].weight, 0);
  // A weak flow term in stages 1 and 3 (0.01 blurred fast motion on real
  // footage into fog).
  EXPECT_EQ(c.stages[0].losses[LossTerm::kFlow].weight, 0.002);
  EXPECT_EQ(c.stages[2].losses[LossTerm::kFlow].weight, 0.002);
  EXPECT_EQ(s2.losses[LossTerm::kFeatureMatch].weight, 0);
  EXPECT_LT(s2.losses[LossTerm::kSilhouette].weight,
            c.stages[0].losses[LossTerm::kSilhouette].weight);
  using G = ParameterGroup;
  const std::set<G> constant2(s2.constant.begin(), s2.constant.end());
  EXPECT_EQ(constant2, (std::set<G>{G::kSdf, G::kColor, G::kEmbedding, G::kLogBeta, G::kAppearance,
                                    G::kRoot, G::kIntrinsics}));
  // Stage 3: importance depth + active sampling, root poses fixed.
  const StageConfig& s3 = c.stages[2];
  EXPECT_TRUE(s3.sampling.importance_depth);
  EXPECT_EQ(s3.sampling.active_fraction, 0.1);
  // Every stage draws 20 % of its rays inside the mask, the rest from the
  // mask's box x 1.5.
  for (const StageConfig& s : c.stages) {
    EXPECT_EQ(s.sampling.crop_scale, 1.5) << s.name;
    EXPECT_EQ(s.sampling.foreground_fraction, 0.2) << s.name;
  }
  // ... starting from the bones registered once more, with the mask term.
  EXPECT_EQ(s3.bone_registration.at, (std::vector<double>{0.0, 1.0}));
  EXPECT_EQ(s3.bone_registration.mask_weight, 10.0);
  // ... and after its last batch with the masks counting more than the
  // matches (the finished shape; no later batch moves the fit).
  const BoneRegistrationConfig last = s3.bone_registration.AfterLastBatch();
  EXPECT_GT(last.mask_weight / last.match_weight,
            s3.bone_registration.mask_weight / s3.bone_registration.match_weight);
  EXPECT_GT(last.coverage_weight / last.match_weight,
            s3.bone_registration.coverage_weight / s3.bone_registration.match_weight);
  EXPECT_TRUE(s2.bone_registration.at.empty());
  EXPECT_NE(std::find(s3.constant.begin(), s3.constant.end(), G::kRoot), s3.constant.end());
  // ... rendered with NeuS's density and unbiased silhouettes (VolSDF before).
  EXPECT_EQ(c.model.density, DensityModel::kVolSdf);
  EXPECT_EQ(s3.schedule.neus_from, 0.0);
  EXPECT_TRUE(s3.sampling.unbiased_silhouette);
  EXPECT_GE(c.stages[0].schedule.neus_from, 1.0);
  // ... and a Cauchy silhouette, in stage 3 only (in stage 1 it cost the
  // oracle 17 %: benchmarks/log/2026-12.md).
  EXPECT_EQ(s3.losses[LossTerm::kSilhouette].robust.type, RobustLossType::kCauchy);
  EXPECT_EQ(s3.losses[LossTerm::kSilhouette].robust.scale, 1.0);
  EXPECT_EQ(c.stages[0].losses[LossTerm::kSilhouette].robust.type, RobustLossType::kNone);
  // The defaults block reached every stage; stage 3 takes 32 samples a ray.
  for (const StageConfig& s : c.stages) {
    EXPECT_EQ(s.batch_rays, 512);
    EXPECT_EQ(s.samples_per_ray, &s == &s3 ? 32 : 24);
  }
  EXPECT_EQ(
      LoadSolverConfig(std::string(BANMO_SOURCE_DIR) + "/problems/rigid.yaml").model.num_bones, 0);
}

TEST(SolverConfig, UnknownKeysNamePathAndLine) {
  struct Case {
    std::string yaml;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"stages: [{}]\nfoo: 1\n", "test.yaml: unknown key 'foo' (line 2)"},
      {"model:\n  num_bone: 3\nstages: [{}]\n", "test.yaml: unknown key 'model.num_bone' (line 2)"},
      {"model:\n  field:\n    position_encoding:\n      num_bandz: 3\nstages: [{}]\n",
       "test.yaml: unknown key 'model.field.position_encoding.num_bandz' (line 4)"},
      {"stages:\n  - name: a\n  - name: b\n    adam:\n      lrr: 0.1\n",
       "test.yaml: unknown key 'stages[1].adam.lrr' (line 5)"},
      {"stages:\n  - losses:\n      rgb:\n        robust: {typ: huber}\n",
       "test.yaml: unknown key 'stages[0].losses.rgb.robust.typ' (line 4)"},
      {"defaults:\n  sampling:\n    foo: 1\nstages: [{}]\n",
       "test.yaml: unknown key 'defaults.sampling.foo' (line 3)"},
      {"stages:\n  - name: a\n    name: b\n", "test.yaml: duplicate key 'stages[0].name' (line 3)"},
      {"model:\n  auto_size: {enabled: true, max_bone: 8}\nstages: [{}]\n",
       "test.yaml: unknown key 'model.auto_size.max_bone' (line 2)"},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(ParseError(c.yaml), c.message) << c.yaml;
  }
}

TEST(SolverConfig, WrongTypesNameKeyAndExpectedType) {
  struct Case {
    std::string yaml;
    std::vector<std::string> parts;  // all must appear in the message
  };
  const std::vector<Case> cases = {
      {"stages:\n  - iterations: abc\n",
       {"test.yaml: key 'stages[0].batches' (line 2)", "expected an integer", "'abc'"}},
      {"stages:\n  - batches: 1.5\n", {"'stages[0].batches'", "an integer"}},
      {"stages:\n  - batches: 99999999999\n", {"'stages[0].batches'", "an integer"}},
      {"stages:\n  - losses: {rgb: {weight: [1]}}\n",
       {"'stages[0].losses.rgb.weight'", "a finite number", "got a list"}},
      {"stages:\n  - losses: {rgb: {weight: .nan}}\n", {"rgb.weight'", "a finite number"}},
      {"stages:\n  - sampling: {importance_depth: 3}\n",
       {"'stages[0].sampling.importance_depth'", "true or false"}},
      {"stages:\n  - sampling: {flow_gaps: [1, x]}\n",
       {"'stages[0].sampling.flow_gaps[1]'", "an integer", "'x'"}},
      {"stages:\n  - sampling: {flow_gaps: 4}\n", {"'stages[0].sampling.flow_gaps'", "a list"}},
      {"stages:\n  - adam: 5\n", {"'stages[0].adam'", "expected a map", "'5'"}},
      {"stages:\n  - constant: sdf\n", {"'stages[0].constant'", "a list"}},
      {"stages:\n  - name: [a]\n", {"'stages[0].name'", "a string"}},
      {"model: {field: {activation: tanh}}\nstages: [{}]\n",
       {"model.field.activation: expected one of {softplus, relu}", "'tanh'"}},
      {"seed: -1\nstages: [{}]\n", {"key 'seed' (line 1)", "0..4294967295"}},
      {"threads: two\nstages: [{}]\n", {"key 'threads'", "an integer"}},
      {"stages: {a: 1}\n", {"key 'stages'", "a list of stages"}},
      {"- 1\n- 2\n", {"test.yaml", "(top level)", "a map"}},
      {"stages: [{}\n", {"test.yaml", "invalid YAML", "line"}},
  };
  for (const Case& c : cases) {
    const std::string message = ParseError(c.yaml);
    for (const std::string& part : c.parts) {
      EXPECT_NE(message.find(part), std::string::npos)
          << "yaml:\n"
          << c.yaml << "message: " << message << "\nmissing: " << part;
    }
  }
}

TEST(SolverConfig, EmptyOrMissingStagesAreErrors) {
  EXPECT_NE(ParseError("stages: []\n").find("test.yaml: stages: expected a non-empty list"),
            std::string::npos);
  EXPECT_NE(ParseError("seed: 1\n").find("'stages'"), std::string::npos);
  EXPECT_NE(ParseError("").find("test.yaml: empty config"), std::string::npos);
  SolverConfig c;
  EXPECT_NE(ErrorOf([&] { CheckSolverConfig(c, "x"); }).find("x: stages:"), std::string::npos);
}

TEST(SolverConfig, LoadNamesTheFile) {
  const fs::path dir =
      fs::temp_directory_path() / ("banmo_config_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "bad.yaml").string();
  {
    std::ofstream out(path);
    out << "stages:\n  - lm: {linear_solver: dense_qr}\n";
  }
  const std::string message = ErrorOf([&] { LoadSolverConfig(path); });
  EXPECT_EQ(message.rfind(path + ": stages[0].lm.linear_solver: expected one of", 0), 0u)
      << message;
  EXPECT_NE(ErrorOf([&] {
              LoadSolverConfig((dir / "missing.yaml").string());
            }).find("missing.yaml: cannot open"),
            std::string::npos);
  fs::remove_all(dir);
}

// Each violated constraint gives an error naming its key.
TEST(SolverConfig, EveryConstraintNamesItsKey) {
  struct Case {
    std::string key;  // expected in the message as "x.yaml: <key>"
    std::function<void(SolverConfig*)> mutate;
  };
  auto S = [](SolverConfig* c) -> StageConfig& { return c->stages[1]; };
  const std::vector<Case> cases = {
      {"threads", [](SolverConfig* c) { c->threads = -1; }},
      {"model.num_bones", [](SolverConfig* c) { c->model.num_bones = 257; }},
      {"model.num_bones", [](SolverConfig* c) { c->model.num_bones = -1; }},
      {"model.init_bone_scale", [](SolverConfig* c) { c->model.init_bone_scale = 0; }},
      {"model.init_beta", [](SolverConfig* c) { c->model.init_beta = -1; }},
      {"model.scene_scale", [](SolverConfig* c) { c->model.scene_scale = 0.0; }},
      {"model.scene_scale", [](SolverConfig* c) { c->model.scene_scale = -2.5; }},
      {"model.field.sdf_width", [](SolverConfig* c) { c->model.field.sdf_width = 0; }},
      {"model.field.sdf_layers", [](SolverConfig* c) { c->model.field.sdf_layers = 0; }},
      {"model.field.position_encoding.num_bands",
       [](SolverConfig* c) { c->model.field.position_encoding.num_bands = -1; }},
      {"model.field.position_encoding.include_input",
       [](SolverConfig* c) { c->model.field.position_encoding.include_input = false; }},
      {"model.field.view_encoding.base_frequency",
       [](SolverConfig* c) { c->model.field.view_encoding.base_frequency = 0; }},
      {"model.field.softplus_beta", [](SolverConfig* c) { c->model.field.softplus_beta = 0; }},
      {"model.field:",
       [](SolverConfig* c) {
         c->model.field.geometry_feature_dim = 0;
         c->model.field.use_view_direction = false;
         c->model.field.appearance_code_dim = 0;
       }},
      {"stages[1].name", [&](SolverConfig* c) { S(c).name = ""; }},
      {"stages[1].batches", [&](SolverConfig* c) { S(c).batches = 0; }},
      {"stages[1].batch_rays", [&](SolverConfig* c) { S(c).batch_rays = 0; }},
      {"stages[1].samples_per_ray", [&](SolverConfig* c) { S(c).samples_per_ray = -2; }},
      {"stages[1].losses.rgb.weight",
       [&](SolverConfig* c) { S(c).losses[LossTerm::kRgb].weight = -1; }},
      {"stages[1].losses.flow.robust.scale",
       [&](SolverConfig* c) { S(c).losses[LossTerm::kFlow].robust.scale = 0; }},
      {"stages[1].losses:",
       [&](SolverConfig* c) {
         for (LossConfig& x : S(c).losses.terms) x.weight = 0;
       }},
      {"stages[1].losses.bone_inside_margin",
       [&](SolverConfig* c) { S(c).losses.bone_inside_margin = -0.1; }},
      {"stages[1].constant[1]",
       [&](SolverConfig* c) {
         S(c).constant = {ParameterGroup::kSdf, ParameterGroup::kSdf};
       }},
      {"stages[1].constant:",
       [&](SolverConfig* c) {
         using G = ParameterGroup;
         S(c).constant = {G::kSdf,  G::kColor, G::kEmbedding, G::kLogBeta,   G::kAppearance,
                          G::kRoot, G::kBones, G::kBonesT,    G::kIntrinsics};
       }},
      {"stages[1].adam.lr", [&](SolverConfig* c) { S(c).adam.lr = 0; }},
      {"stages[1].adam.beta1", [&](SolverConfig* c) { S(c).adam.beta1 = 1; }},
      {"stages[1].adam.beta2", [&](SolverConfig* c) { S(c).adam.beta2 = -0.1; }},
      {"stages[1].adam.epsilon", [&](SolverConfig* c) { S(c).adam.epsilon = 0; }},
      {"stages[1].adam.weight_decay", [&](SolverConfig* c) { S(c).adam.weight_decay = -1; }},
      {"stages[1].adam.warmup_fraction", [&](SolverConfig* c) { S(c).adam.warmup_fraction = 1.5; }},
      {"stages[1].adam.final_lr_fraction",
       [&](SolverConfig* c) { S(c).adam.final_lr_fraction = -0.5; }},
      {"stages[1].adam.pose_lr_scale", [&](SolverConfig* c) { S(c).adam.pose_lr_scale = 0; }},
      {"stages[1].adam.bone_lr_scale", [&](SolverConfig* c) { S(c).adam.bone_lr_scale = -1; }},
      {"stages[1].adam.beta_lr_scale", [&](SolverConfig* c) { S(c).adam.beta_lr_scale = 0; }},
      {"stages[1].adam.intrinsics_lr_scale",
       [&](SolverConfig* c) { S(c).adam.intrinsics_lr_scale = 0; }},
      {"stages[1].adam.bone_basis", [&](SolverConfig* c) { S(c).adam.bone_basis = -1; }},
      {"stages[1].adam.root_basis", [&](SolverConfig* c) { S(c).adam.root_basis = -2; }},
      {"stages[1].lm.max_cg_iterations", [&](SolverConfig* c) { S(c).lm.max_cg_iterations = 0; }},
      {"stages[1].lm.initial_radius", [&](SolverConfig* c) { S(c).lm.initial_radius = 0; }},
      {"stages[1].lm.max_radius", [&](SolverConfig* c) { S(c).lm.max_radius = 10; }},
      {"stages[1].lm.iterations_per_batch",
       [&](SolverConfig* c) { S(c).lm.iterations_per_batch = 0; }},
      {"stages[1].sampling.foreground_fraction",
       [&](SolverConfig* c) { S(c).sampling.foreground_fraction = 1.1; }},
      {"stages[1].sampling.boundary_fraction",
       [&](SolverConfig* c) { S(c).sampling.boundary_fraction = -0.1; }},
      {"stages[1].sampling.boundary_fraction",
       [&](SolverConfig* c) {
         S(c).sampling.foreground_fraction = 0.6;
         S(c).sampling.boundary_fraction = 0.5;
       }},
      {"stages[1].sampling.active_fraction",
       [&](SolverConfig* c) { S(c).sampling.active_fraction = -0.1; }},
      {"stages[1].sampling.crop_scale", [&](SolverConfig* c) { S(c).sampling.crop_scale = 0.5; }},
      {"stages[1].sampling.crop_scale", [&](SolverConfig* c) { S(c).sampling.crop_scale = -1; }},
      {"stages[1].sampling.near_far_margin",
       [&](SolverConfig* c) { S(c).sampling.near_far_margin = -1; }},
      {"stages[1].sampling.importance_samples",
       [&](SolverConfig* c) {
         S(c).sampling.importance_depth = true;
         S(c).sampling.importance_samples = -1;
       }},
      {"stages[1].sampling.importance_samples",  // added samples without the importance pass
       [&](SolverConfig* c) {
         S(c).sampling.importance_depth = false;
         S(c).sampling.importance_samples = 16;
       }},
      {"stages[1].sampling.min_sdf_sample",  // the minimum comes from the importance pass
       [&](SolverConfig* c) {
         S(c).sampling.importance_depth = false;
         S(c).sampling.min_sdf_sample = true;
       }},
      {"stages[1].sampling.flow_gaps[2]",
       [&](SolverConfig* c) {
         S(c).sampling.flow_gaps = {1, 2, 0};
       }},
      {"stages[1].sampling.flow_gaps:", [&](SolverConfig* c) { S(c).sampling.flow_gaps = {}; }},
      {"stages[1].sampling.eikonal_points",
       [&](SolverConfig* c) { S(c).sampling.eikonal_points = 0; }},
      {"stages[1].sampling.match_grid_points",
       [&](SolverConfig* c) { S(c).sampling.match_grid_points = 0; }},
      {"stages[1].sampling.match_top_k", [&](SolverConfig* c) { S(c).sampling.match_top_k = 0; }},
      {"stages[1].sampling.frames_per_batch",
       [&](SolverConfig* c) { S(c).sampling.frames_per_batch = -1; }},
      {"stages[1].sampling.clip_margin",
       [&](SolverConfig* c) { S(c).sampling.clip_margin = -0.1; }},
      {"stages[1].sampling.unbiased_silhouette",
       [&](SolverConfig* c) {
         S(c).sampling.unbiased_silhouette = true;
         S(c).sampling.foreground_fraction = 1.0;
       }},
      {"stages[1].sampling.unbiased_silhouette",  // no uniform draws left
       [&](SolverConfig* c) {
         S(c).sampling.unbiased_silhouette = true;
         S(c).sampling.foreground_fraction = 0.5;
         S(c).sampling.boundary_fraction = 0.5;
       }},
      {"stages[1].sampling.match_top_k",
       [&](SolverConfig* c) { S(c).sampling.match_top_k = S(c).sampling.match_grid_points + 1; }},
      {"stages[1].schedule.bone_reinit_at[0]",
       [&](SolverConfig* c) { S(c).schedule.bone_reinit_at = {1.2}; }},
      {"stages[1].schedule.bone_reinit_at[1]",
       [&](SolverConfig* c) {
         S(c).schedule.bone_reinit_at = {0.5, 0.2};
       }},
      {"stages[1].schedule.bone_reinit_at[1]",  // rounds to the batch count: never runs
       [&](SolverConfig* c) {
         S(c).batches = 100;
         S(c).schedule.bone_reinit_at = {0.2, 0.996};
       }},
      {"stages[1].schedule.freeze_after_reinit",
       [&](SolverConfig* c) {
         S(c).schedule.bone_reinit_at = {0.2};
         S(c).schedule.freeze_after_reinit = 1.5;
       }},
      {"stages[1].schedule.freeze_after_reinit",  // nothing to follow
       [&](SolverConfig* c) { S(c).schedule.freeze_after_reinit = 0.05; }},
      {"stages[1].schedule.bounds_refresh_every",
       [&](SolverConfig* c) { S(c).schedule.bounds_refresh_every = -1; }},
      {"stages[1].schedule.bounds_refresh_max_mask_loss",
       [&](SolverConfig* c) { S(c).schedule.bounds_refresh_max_mask_loss = -0.1; }},
      {"stages[1].schedule.anneal_end_fraction",
       [&](SolverConfig* c) { S(c).schedule.anneal_end_fraction = 2; }},
      {"stages[1].schedule.delta_skinning_from",
       [&](SolverConfig* c) { S(c).schedule.delta_skinning_from = 0.5; }},  // model has none
      {"stages[1].schedule.delta_skinning_from",
       [&](SolverConfig* c) { S(c).schedule.delta_skinning_from = -0.5; }},
      {"stages[1].schedule.root_free_from",
       [&](SolverConfig* c) { S(c).schedule.root_free_from = 1.5; }},
      {"stages[1].schedule.unbiased_silhouette_from",
       [&](SolverConfig* c) { S(c).schedule.unbiased_silhouette_from = -0.1; }},
      {"stages[1].schedule.neus_from", [&](SolverConfig* c) { S(c).schedule.neus_from = -0.1; }},
      {"stages[1].schedule.unbiased_silhouette_from",
       [&](SolverConfig* c) {
         S(c).schedule.unbiased_silhouette_from = 0.5;
         S(c).sampling.foreground_fraction = 1.0;
       }},
      {"stages[1].pose_solve.at[0]", [&](SolverConfig* c) { S(c).pose_solve.at = {-0.1}; }},
      {"stages[1].pose_solve.at[1]",
       [&](SolverConfig* c) {
         S(c).pose_solve.at = {0.5, 0.5};
       }},
      {"stages[1].pose_solve.at[0]",  // after the last batch: never runs
       [&](SolverConfig* c) {
         S(c).batches = 10;
         S(c).pose_solve.at = {1.0};
       }},
      {"stages[1].pose_solve.at",
       [&](SolverConfig* c) {
         S(c).pose_solve.at = {0.5};
         S(c).constant = {ParameterGroup::kRoot};
       }},
      {"stages[1].pose_solve.at",  // while the schedule holds the root
       [&](SolverConfig* c) {
         S(c).pose_solve.at = {0.2};
         S(c).schedule.root_free_from = 0.3;
       }},
      {"stages[1].pose_solve.every", [&](SolverConfig* c) { S(c).pose_solve.every = -1; }},
      {"stages[1].pose_solve.every",  // alternate moves the per-frame blocks only in pose solves
       [&](SolverConfig* c) { S(c).step_rule = StepRule::kAlternate; }},
      {"stages[1].pose_solve.every",
       [&](SolverConfig* c) {
         S(c).pose_solve.every = 10;
         S(c).constant = {ParameterGroup::kRoot};
       }},
      {"stages[1].pose_solve.rays", [&](SolverConfig* c) { S(c).pose_solve.rays = 0; }},
      {"stages[1].pose_solve.iterations", [&](SolverConfig* c) { S(c).pose_solve.iterations = 0; }},
      {"stages[1].pose_solve.search_ratio",
       [&](SolverConfig* c) { S(c).pose_solve.search_ratio = -1; }},
      {"stages[1].pose_solve.search_rotations",
       [&](SolverConfig* c) { S(c).pose_solve.search_rotations = 0; }},
      {"stages[1].pose_solve.search_keep",
       [&](SolverConfig* c) { S(c).pose_solve.search_keep = 100; }},
      {"stages[1].bone_registration.at[0]",
       [&](SolverConfig* c) { S(c).bone_registration.at = {1.5}; }},
      {"stages[1].bone_registration.at",
       [&](SolverConfig* c) {
         S(c).bone_registration.at = {0.5};
         S(c).constant = {ParameterGroup::kBonesT};
       }},
      {"stages[1].bone_registration.resolution",
       [&](SolverConfig* c) { S(c).bone_registration.resolution = 0; }},
      {"stages[1].bone_registration.vertices",
       [&](SolverConfig* c) { S(c).bone_registration.vertices = 0; }},
      {"stages[1].bone_registration.match_pixels",
       [&](SolverConfig* c) { S(c).bone_registration.match_pixels = -1; }},
      {"stages[1].bone_registration.match_weight",
       [&](SolverConfig* c) { S(c).bone_registration.match_weight = 0; }},
      {"stages[1].bone_registration.huber_px",
       [&](SolverConfig* c) { S(c).bone_registration.huber_px = -2; }},
      {"stages[1].bone_registration.joint_weight",
       [&](SolverConfig* c) { S(c).bone_registration.joint_weight = -1; }},
      {"stages[1].bone_registration.joint_min_weight",
       [&](SolverConfig* c) { S(c).bone_registration.joint_min_weight = 1.5; }},
      {"stages[1].bone_registration.joint_points",
       [&](SolverConfig* c) { S(c).bone_registration.joint_points = -1; }},
      {"stages[1].bone_registration.smooth_weight",
       [&](SolverConfig* c) { S(c).bone_registration.smooth_weight = -0.1; }},
      {"stages[1].bone_registration.rest_weight",
       [&](SolverConfig* c) { S(c).bone_registration.rest_weight = -0.1; }},
      {"stages[1].bone_registration.visible_tolerance",
       [&](SolverConfig* c) { S(c).bone_registration.visible_tolerance = 0; }},
      {"stages[1].bone_registration.iterations",
       [&](SolverConfig* c) { S(c).bone_registration.iterations = 0; }},
      {"stages[1].bone_registration.mask_weight",
       [&](SolverConfig* c) { S(c).bone_registration.mask_weight = -1; }},
      {"stages[1].bone_registration.mask_points",
       [&](SolverConfig* c) { S(c).bone_registration.mask_points = 0; }},
      {"stages[1].bone_registration.coverage_weight",
       [&](SolverConfig* c) { S(c).bone_registration.coverage_weight = -1; }},
      {"stages[1].bone_registration.coverage_pixels",
       [&](SolverConfig* c) { S(c).bone_registration.coverage_pixels = 0; }},
      {"stages[1].bone_registration.coverage_rounds",
       [&](SolverConfig* c) { S(c).bone_registration.coverage_rounds = 0; }},
      {"stages[1].bone_registration.after_last_batch.match_weight",
       [&](SolverConfig* c) { S(c).bone_registration.after_last_batch.match_weight = 0; }},
      {"stages[1].bone_registration.after_last_batch.mask_weight",
       [&](SolverConfig* c) { S(c).bone_registration.after_last_batch.mask_weight = -1; }},
      {"stages[1].bone_registration.after_last_batch.coverage_weight",
       [&](SolverConfig* c) { S(c).bone_registration.after_last_batch.coverage_weight = -1; }},
      {"stages[1].bone_registration.after_last_batch",  // no registration there
       [&](SolverConfig* c) {
         S(c).bone_registration.at = {0.5};
         S(c).bone_registration.after_last_batch.mask_weight = 20;
       }},
      {"model.delta_skinning.width",
       [&](SolverConfig* c) {
         c->model.delta_skinning.enabled = true;
         c->model.delta_skinning.width = 0;
       }},
      {"model.delta_skinning.enabled",
       [&](SolverConfig* c) {
         c->model.delta_skinning.enabled = true;
         c->model.num_bones = 0;
       }},
      {"model.auto_size.enabled",
       [&](SolverConfig* c) {
         c->model.auto_size.enabled = true;
         c->model.delta_skinning.enabled = true;
       }},
      {"model.auto_size.max_bones",
       [&](SolverConfig* c) {
         c->model.auto_size.enabled = true;
         c->model.auto_size.max_bones = c->model.num_bones - 1;
       }},
      {"model.auto_size.max_bones", [&](SolverConfig* c) { c->model.auto_size.max_bones = 257; }},
      {"model.auto_size.grow_at[0]", [&](SolverConfig* c) { c->model.auto_size.grow_at = {1.5}; }},
      {"model.auto_size.grow_at[1]",
       [&](SolverConfig* c) {
         c->model.auto_size.grow_at = {0.5, 0.5};
       }},
      {"model.auto_size.grow_at[2]",  // rounds to stage 0's batch count: never runs
       [&](SolverConfig* c) {
         c->model.auto_size.enabled = true;
         c->stages[0].batches = 100;
         c->model.auto_size.grow_at = {0.4, 0.55, 0.996};
       }},
      {"model.auto_size.error_ratio",
       [&](SolverConfig* c) { c->model.auto_size.error_ratio = 0.9; }},
      {"model.auto_size.eval_rays", [&](SolverConfig* c) { c->model.auto_size.eval_rays = 0; }},
      {"model.root_init_smoothing.acceleration_deg",
       [&](SolverConfig* c) { c->model.root_init_smoothing.acceleration_deg = 0; }},
      {"model.root_init_smoothing.robust_sigmas",
       [&](SolverConfig* c) { c->model.root_init_smoothing.robust_sigmas = -1; }},
      {"model.root_init_registration.references",
       [&](SolverConfig* c) { c->model.root_init_registration.references = 8; }},
      {"model.auto_size.max_width", [&](SolverConfig* c) { c->model.auto_size.max_width = -1; }},
      {"model.auto_size.max_width",
       [&](SolverConfig* c) {
         c->model.auto_size.enabled = true;
         c->model.auto_size.max_width = c->model.field.sdf_width - 1;
       }},
      {"stages[1].bone_steps_articulated",
       [&](SolverConfig* c) {
         S(c).bone_steps_articulated = true;
         S(c).bone_steps_about_centres = true;
       }},
      {"stages[1].checkpoint_every", [&](SolverConfig* c) { S(c).checkpoint_every = -1; }},
      {"stages[1].log_every", [&](SolverConfig* c) { S(c).log_every = -1; }},
  };
  SolverConfig valid;
  valid.stages.resize(2);
  ASSERT_NO_THROW(CheckSolverConfig(valid, "x.yaml"));
  for (const Case& c : cases) {
    SolverConfig config = valid;
    c.mutate(&config);
    const std::string message = ErrorOf([&] { CheckSolverConfig(config, "x.yaml"); });
    EXPECT_EQ(message.rfind("x.yaml: " + c.key, 0), 0u)
        << "expected key " << c.key << ", message: '" << message << "'";
    // The same violation written as YAML fails the parse with the same
    // message plus the key's line.
    const std::string yaml = SolverConfigToYaml(config);
    const std::string parse_message = ErrorOf([&] { ParseSolverConfig(yaml, "x.yaml"); });
    EXPECT_EQ(parse_message.rfind(message + " (line ", 0), 0u) << parse_message;
  }
}

// pose_solve.bones solves the bone transforms: a stage that holds the root
// constant may then have pose solves, and a stage of pose solves alone
// (every group constant) is not empty.
// Each section checks itself (its Check() beside the struct) and names the
// key path it is given.
TEST(SolverConfig, SectionsCheckThemselvesUnderTheirKeyPath) {
  const std::string source = "s.yaml";
  const OptionChecker c(source);
  auto message = [](const std::function<void()>& check) {
    try {
      check();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  AdamConfig adam;
  EXPECT_EQ(message([&] { adam.Check(c, "x.adam"); }), "no error");
  adam.beta2 = 1.0;
  EXPECT_EQ(message([&] { adam.Check(c, "x.adam"); }).rfind("s.yaml: x.adam.beta2: ", 0), 0u);
  PoseSolveConfig pose;
  pose.at = {0.5, 1.0};
  EXPECT_NE(message([&] { pose.Check(c, "y", 10); }).find("s.yaml: y.at[1]: "), std::string::npos);
  BoneRegistrationConfig reg;
  reg.after_last_batch.mask_weight = -1.0;
  EXPECT_EQ(message([&] { reg.Check(c, "z"); }).rfind("s.yaml: z.after_last_batch.mask_weight", 0),
            0u);
  // A rule across sections is the stage's: registration against constant.
  StageConfig stage;
  stage.bone_registration.at = {0.5};
  stage.constant = {ParameterGroup::kBonesT};
  EXPECT_EQ(message([&] {
              stage.Check(c, "stages[3]");
            }).rfind("s.yaml: stages[3].bone_registration.at: a bone registration moves", 0),
            0u);
}

TEST(SolverConfig, BonePoseSolvesMayHoldTheRootOrEverything) {
  SolverConfig config;
  config.stages.resize(2);
  StageConfig& s = config.stages[1];
  s.constant = {ParameterGroup::kRoot};
  s.pose_solve.at = {0.5};
  EXPECT_NE(ErrorOf([&] { CheckSolverConfig(config, "x.yaml"); }).find("stages[1].pose_solve.at"),
            std::string::npos);
  s.pose_solve.bones = true;
  EXPECT_NO_THROW(CheckSolverConfig(config, "x.yaml"));
  s.constant.clear();
  for (const auto& [group, name] : EnumNames<ParameterGroup>::kNames) s.constant.push_back(group);
  s.pose_solve.at = {0.0};
  EXPECT_NO_THROW(CheckSolverConfig(config, "x.yaml"));
  s.pose_solve.at.clear();
  EXPECT_NE(ErrorOf([&] {
              CheckSolverConfig(config, "x.yaml");
            }).find("stages[1].constant: every parameter group is constant"),
            std::string::npos);
  s.pose_solve.every = 50;  // pose solves every 50 batches are something to do
  EXPECT_NO_THROW(CheckSolverConfig(config, "x.yaml"));
}

// The alternate rule's per-frame root corrections (and with
// pose_solve.bones its bone transforms) move only in pose solves: it needs
// a schedule of them unless the stage holds what they would solve.
TEST(SolverConfig, AlternateNeedsPoseSolvesForItsPerFrameBlocks) {
  SolverConfig config;
  config.stages.resize(1);
  StageConfig& s = config.stages[0];
  s.step_rule = StepRule::kAlternate;
  EXPECT_NE(ErrorOf([&] { CheckSolverConfig(config, "x.yaml"); })
                .find("stages[0].pose_solve.every: step_rule alternate moves the per-frame root "
                      "corrections (and with pose_solve.bones the bone transforms) only in pose "
                      "solves"),
            std::string::npos);
  s.pose_solve.every = 100;
  EXPECT_NO_THROW(CheckSolverConfig(config, "x.yaml"));
  s.pose_solve.every = 0;
  s.pose_solve.at = {0.5};
  EXPECT_NO_THROW(CheckSolverConfig(config, "x.yaml"));
  // Root held: Adam moves everything else, no solve needed ...
  s.pose_solve.at.clear();
  s.constant = {ParameterGroup::kRoot};
  EXPECT_NO_THROW(CheckSolverConfig(config, "x.yaml"));
  // ... unless the solves own the bone transforms.
  s.pose_solve.bones = true;
  EXPECT_NE(
      ErrorOf([&] { CheckSolverConfig(config, "x.yaml"); }).find("stages[0].pose_solve.every"),
      std::string::npos);
  s.pose_solve.every = 50;
  EXPECT_NO_THROW(CheckSolverConfig(config, "x.yaml"));
}

TEST(SolverConfig, ConstraintErrorsFromYamlGiveTheLine) {
  // The key itself.
  EXPECT_EQ(ParseError("stages:\n  - name: a\n  - adam:\n      lr: -1\n"),
            "test.yaml: stages[1].adam.lr: expected a number in (0, 100], got -1 (line 4)");
  // A value inherited from defaults: the line in `defaults:`.
  EXPECT_EQ(ParseError("defaults:\n  batch_rays: 0\nstages:\n  - name: a\n"),
            "test.yaml: stages[0].batch_rays: expected an integer in [1, 65536], got 0 (line 2)");
  // A key not written: its nearest written parent.
  EXPECT_EQ(ParseError("stages:\n  - name: a\n    sampling: {match_grid_points: 8}\n"),
            "test.yaml: stages[0].sampling.match_top_k: expected <= sampling.match_grid_points "
            "(8), got 32 (line 3)");
  // A list element.
  EXPECT_EQ(ParseError("stages:\n  - constant:\n      - sdf\n      - shape\n")
                .find("stages[0].constant[1]: expected one of"),
            std::string("test.yaml: ").size());
  EXPECT_NE(ParseError("stages:\n  - constant:\n      - sdf\n      - shape\n").find("(line 4)"),
            std::string::npos);
  // Model keys.
  EXPECT_EQ(ParseError("stages: [{}]\nmodel:\n  field:\n    sdf_width: 0\n"),
            "test.yaml: model.field.sdf_width must be in [1, 4096], got 0 (line 4)");
}

TEST(SolverConfig, DefaultsMergeUnderEveryStage) {
  const SolverConfig c = ParseSolverConfig(R"(
defaults:
  batch_rays: 512
  constant: [root, intrinsics]
  adam: {lr: 0.01, beta1: 0.8}
  sampling: {flow_gaps: [3]}
stages:
  - name: a
  - name: b
    adam: {beta1: 0.5}
    constant: [sdf]
    sampling: {importance_depth: true}
  - batch_rays: 64
    constant: []
)",
                                           "test.yaml");
  ASSERT_EQ(c.stages.size(), 3u);
  const StageConfig d;
  const StageConfig& a = c.stages[0];
  EXPECT_EQ(a.name, "a");
  EXPECT_EQ(a.batch_rays, 512);
  EXPECT_EQ(a.adam.lr, 0.01);
  EXPECT_EQ(a.adam.beta1, 0.8);
  EXPECT_EQ(a.adam.beta2, d.adam.beta2);  // untouched keys keep the struct default
  EXPECT_EQ(a.constant,
            (std::vector<ParameterGroup>{ParameterGroup::kRoot, ParameterGroup::kIntrinsics}));
  EXPECT_EQ(a.sampling.flow_gaps, std::vector<int>{3});
  EXPECT_EQ(a.samples_per_ray, d.samples_per_ray);
  // Maps merge key by key; lists replace.
  const StageConfig& b = c.stages[1];
  EXPECT_EQ(b.adam.lr, 0.01);
  EXPECT_EQ(b.adam.beta1, 0.5);
  EXPECT_EQ(b.constant, std::vector<ParameterGroup>{ParameterGroup::kSdf});
  EXPECT_TRUE(b.sampling.importance_depth);
  EXPECT_EQ(b.sampling.flow_gaps, std::vector<int>{3});
  EXPECT_EQ(b.batch_rays, 512);
  const StageConfig& s3 = c.stages[2];
  EXPECT_EQ(s3.name, d.name);
  EXPECT_EQ(s3.batch_rays, 64);
  EXPECT_TRUE(s3.constant.empty());
  EXPECT_FALSE(s3.sampling.importance_depth);
}

// Sets every field to a value different from its default.
SolverConfig EveryFieldChanged() {
  SolverConfig c;
  ModelOptions& m = c.model;
  m.field.position_encoding = {5, true, 0.75};
  m.field.sdf_width = 24;
  m.field.sdf_layers = 4;
  m.field.geometry_feature_dim = 3;
  m.field.color_width = 20;
  m.field.color_layers = 1;
  m.field.use_view_direction = false;
  m.field.view_encoding = {2, false, 0.5};
  m.field.appearance_code_dim = 7;
  m.field.embedding_width = 12;
  m.field.embedding_layers = 3;
  m.field.activation = Activation::kRelu;
  m.field.softplus_beta = 37.5;
  m.field.init_sphere_radius = 0.3;
  m.num_bones = 13;
  m.init_bone_scale = 0.1 / 3.0;  // not exactly representable in short decimal
  m.init_beta = 0.07;
  m.density = DensityModel::kNeus;
  m.seed = 4000000000u;
  m.delta_skinning.enabled = true;
  m.delta_skinning.width = 24;
  m.delta_skinning.hidden_layers = 3;
  m.delta_skinning.num_bands = 5;
  m.delta_skinning.pose_code_dim = 12;
  m.delta_skinning.code_init_std = 0.07;
  m.scene_scale = 0.1 / 3.0;
  m.recentre = false;
  // auto_size.enabled stays false: it cannot be combined with delta skinning.
  m.auto_size.max_bones = 40;
  m.auto_size.grow_at = {0.25, 0.5};
  m.auto_size.error_ratio = 2.25;
  m.auto_size.eval_rays = 1000;
  m.auto_size.max_width = 96;
  m.root_init_smoothing.enabled = true;
  m.root_init_smoothing.acceleration_deg = 0.1 / 3.0;
  m.root_init_smoothing.robust_sigmas = 2.5;
  m.root_init_registration.enabled = true;
  m.root_init_registration.always = true;
  m.root_init_registration.references = 123;
  c.seed = 123456789u;
  c.threads = 3;
  for (int i = 0; i < 2; ++i) {
    StageConfig s;
    s.name = i == 0 ? "first: stage #1" : "null";  // quoting; "null" must stay a string
    s.batches = 77 + i;
    s.step_rule = i == 0 ? StepRule::kLm : StepRule::kAlternate;
    s.batch_rays = 333;
    s.samples_per_ray = 17;
    double w = 0.1;
    LossesConfig& l = s.losses;
    for (LossConfig& x : l.terms) {
      x.weight = (w += 0.123);
      x.robust = {RobustLossType::kCauchy, w * 2};
    }
    l.bone_inside_margin = 0.031;
    l.feature_render_embedding_only = true;
    s.constant = {ParameterGroup::kSdf, ParameterGroup::kEmbedding};
    s.adam = {1.25e-3, 0.85, 0.995, 1e-10, 1e-4, LrSchedule::kConstant, 0.2, 0.05, 2.5,
              3.5,     4.5,  40,    12,    5};
    s.lm = {9, 123.0, 4.5e7, LinearSolverType::kIterativeSchur, 2};
    s.sampling.foreground_fraction = 0.7;
    s.sampling.boundary_fraction = 0.2;
    s.sampling.active_fraction = 0.15;
    s.sampling.crop_scale = 1.75;
    s.sampling.importance_depth = true;
    s.sampling.importance_samples = 19;
    s.sampling.min_sdf_sample = true;
    s.sampling.near_far_margin = 0.33;
    s.sampling.flow_gaps = {1, 3};
    s.sampling.eikonal_points = 100;
    s.sampling.match_grid_points = 1000;
    s.sampling.match_top_k = 10;
    s.sampling.frames_per_batch = 6;
    s.sampling.unbiased_silhouette = true;
    s.sampling.clip_to_box = true;
    s.sampling.clip_margin = 0.05;
    s.schedule.bone_reinit_at = {0.1, 0.9};
    s.schedule.bone_reinit_keep_motion = true;
    s.schedule.bone_sites = BoneSites::kSkeleton;
    s.schedule.freeze_after_reinit = 0.03;
    s.schedule.bounds_refresh_every = 25;
    s.schedule.bounds_refresh_max_mask_loss = 0.125;
    s.schedule.anneal_end_fraction = 0.4;
    s.schedule.delta_skinning_from = i == 0 ? 1.5 : 0.6;  // >= 1: off in this stage
    s.schedule.root_free_from = 0.15;                     // before pose_solve.at[0]
    s.schedule.unbiased_silhouette_from = 0.35;
    s.schedule.neus_from = 0.45;
    s.pose_solve.at = {0.2, 0.7};
    s.pose_solve.every = 40 + i;
    s.pose_solve.rays = 96;
    s.pose_solve.iterations = 4;
    s.pose_solve.search_ratio = 2.5;
    s.pose_solve.search_rotations = 24;
    s.pose_solve.search_keep = 2;
    s.pose_solve.bones = true;
    s.pose_solve.featureless_only = true;
    s.bone_registration.at = {0.3, 1.0};
    s.bone_registration.resolution = 64 + i;
    s.bone_registration.vertices = 500 + i;
    s.bone_registration.match_pixels = 300 + i;
    s.bone_registration.match_weight = 5 + i;
    s.bone_registration.huber_px = 3 + i;
    s.bone_registration.joint_weight = 2 + i;
    s.bone_registration.joint_min_weight = 0.2 + 0.01 * i;
    s.bone_registration.joint_points = 20 + i;
    s.bone_registration.smooth_weight = 0.03 + 0.01 * i;
    s.bone_registration.rest_weight = 0.02 + 0.01 * i;
    s.bone_registration.visible_tolerance = 0.07 + 0.01 * i;
    s.bone_registration.iterations = 7 + i;
    s.bone_registration.mask_weight = 0.5 + i;
    s.bone_registration.mask_points = 200 + i;
    s.bone_registration.coverage_weight = 1.5 + i;
    s.bone_registration.coverage_pixels = 300 + i;
    s.bone_registration.coverage_rounds = 4 + i;
    s.bone_registration.start = i == 0 ? RegistrationStart::kLowerCost : RegistrationStart::kOwn;
    s.bone_registration.after_last_batch.match_weight = 1.5 + i;
    s.bone_registration.after_last_batch.mask_weight = 20 + i;
    s.bone_registration.after_last_batch.coverage_weight = 25 + i;
    s.bone_steps_about_centres = i == 0;  // the two are exclusive
    s.bone_steps_articulated = i != 0;
    s.checkpoint_every = 50;
    s.log_every = 5;
    c.stages.push_back(s);
  }
  return c;
}

void ExpectSameEncoding(const PositionalEncodingOptions& a, const PositionalEncodingOptions& b) {
  EXPECT_EQ(a.num_bands, b.num_bands);
  EXPECT_EQ(a.include_input, b.include_input);
  EXPECT_EQ(a.base_frequency, b.base_frequency);
}

void ExpectSameLoss(const LossConfig& a, const LossConfig& b) {
  EXPECT_EQ(a.weight, b.weight);
  EXPECT_EQ(a.robust.type, b.robust.type);
  EXPECT_EQ(a.robust.scale, b.robust.scale);
}

// Field by field; doubles compared exactly (the writer prints round-trip
// decimals).
void ExpectSame(const SolverConfig& a, const SolverConfig& b) {
  const CanonicalFieldOptions& f = a.model.field;
  const CanonicalFieldOptions& g = b.model.field;
  ExpectSameEncoding(f.position_encoding, g.position_encoding);
  EXPECT_EQ(f.sdf_width, g.sdf_width);
  EXPECT_EQ(f.sdf_layers, g.sdf_layers);
  EXPECT_EQ(f.geometry_feature_dim, g.geometry_feature_dim);
  EXPECT_EQ(f.color_width, g.color_width);
  EXPECT_EQ(f.color_layers, g.color_layers);
  EXPECT_EQ(f.use_view_direction, g.use_view_direction);
  ExpectSameEncoding(f.view_encoding, g.view_encoding);
  EXPECT_EQ(f.appearance_code_dim, g.appearance_code_dim);
  EXPECT_EQ(f.embedding_width, g.embedding_width);
  EXPECT_EQ(f.embedding_layers, g.embedding_layers);
  EXPECT_EQ(f.activation, g.activation);
  EXPECT_EQ(f.softplus_beta, g.softplus_beta);
  EXPECT_EQ(f.init_sphere_radius, g.init_sphere_radius);
  EXPECT_EQ(a.model.num_bones, b.model.num_bones);
  EXPECT_EQ(a.model.init_bone_scale, b.model.init_bone_scale);
  EXPECT_EQ(a.model.init_beta, b.model.init_beta);
  EXPECT_EQ(a.model.density, b.model.density);
  EXPECT_EQ(a.model.seed, b.model.seed);
  EXPECT_EQ(a.model.delta_skinning.enabled, b.model.delta_skinning.enabled);
  EXPECT_EQ(a.model.delta_skinning.width, b.model.delta_skinning.width);
  EXPECT_EQ(a.model.delta_skinning.hidden_layers, b.model.delta_skinning.hidden_layers);
  EXPECT_EQ(a.model.delta_skinning.num_bands, b.model.delta_skinning.num_bands);
  EXPECT_EQ(a.model.delta_skinning.pose_code_dim, b.model.delta_skinning.pose_code_dim);
  EXPECT_EQ(a.model.delta_skinning.code_init_std, b.model.delta_skinning.code_init_std);
  EXPECT_EQ(a.model.scene_scale, b.model.scene_scale);
  EXPECT_EQ(a.model.recentre, b.model.recentre);
  EXPECT_EQ(a.model.auto_size.enabled, b.model.auto_size.enabled);
  EXPECT_EQ(a.model.auto_size.max_bones, b.model.auto_size.max_bones);
  EXPECT_EQ(a.model.auto_size.grow_at, b.model.auto_size.grow_at);
  EXPECT_EQ(a.model.auto_size.error_ratio, b.model.auto_size.error_ratio);
  EXPECT_EQ(a.model.auto_size.eval_rays, b.model.auto_size.eval_rays);
  EXPECT_EQ(a.model.auto_size.max_width, b.model.auto_size.max_width);
  EXPECT_EQ(a.model.root_init_smoothing.enabled, b.model.root_init_smoothing.enabled);
  EXPECT_EQ(a.model.root_init_smoothing.acceleration_deg,
            b.model.root_init_smoothing.acceleration_deg);
  EXPECT_EQ(a.model.root_init_smoothing.robust_sigmas, b.model.root_init_smoothing.robust_sigmas);
  EXPECT_EQ(a.model.root_init_registration.enabled, b.model.root_init_registration.enabled);
  EXPECT_EQ(a.model.root_init_registration.always, b.model.root_init_registration.always);
  EXPECT_EQ(a.model.root_init_registration.references, b.model.root_init_registration.references);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.threads, b.threads);
  ASSERT_EQ(a.stages.size(), b.stages.size());
  for (size_t i = 0; i < a.stages.size(); ++i) {
    SCOPED_TRACE("stage " + std::to_string(i));
    const StageConfig& s = a.stages[i];
    const StageConfig& t = b.stages[i];
    EXPECT_EQ(s.name, t.name);
    EXPECT_EQ(s.batches, t.batches);
    EXPECT_EQ(s.step_rule, t.step_rule);
    EXPECT_EQ(s.batch_rays, t.batch_rays);
    EXPECT_EQ(s.samples_per_ray, t.samples_per_ray);
    for (const LossTermInfo& info : kLossTable) {
      SCOPED_TRACE(info.key);
      ExpectSameLoss(s.losses[info.term], t.losses[info.term]);
    }
    EXPECT_EQ(s.losses.bone_inside_margin, t.losses.bone_inside_margin);
    EXPECT_EQ(s.losses.feature_render_embedding_only, t.losses.feature_render_embedding_only);
    EXPECT_EQ(s.constant, t.constant);
    EXPECT_EQ(s.adam.lr, t.adam.lr);
    EXPECT_EQ(s.adam.beta1, t.adam.beta1);
    EXPECT_EQ(s.adam.beta2, t.adam.beta2);
    EXPECT_EQ(s.adam.epsilon, t.adam.epsilon);
    EXPECT_EQ(s.adam.weight_decay, t.adam.weight_decay);
    EXPECT_EQ(s.adam.schedule, t.adam.schedule);
    EXPECT_EQ(s.adam.warmup_fraction, t.adam.warmup_fraction);
    EXPECT_EQ(s.adam.final_lr_fraction, t.adam.final_lr_fraction);
    EXPECT_EQ(s.adam.pose_lr_scale, t.adam.pose_lr_scale);
    EXPECT_EQ(s.adam.bone_lr_scale, t.adam.bone_lr_scale);
    EXPECT_EQ(s.adam.beta_lr_scale, t.adam.beta_lr_scale);
    EXPECT_EQ(s.adam.intrinsics_lr_scale, t.adam.intrinsics_lr_scale);
    EXPECT_EQ(s.adam.bone_basis, t.adam.bone_basis);
    EXPECT_EQ(s.adam.root_basis, t.adam.root_basis);
    EXPECT_EQ(s.lm.max_cg_iterations, t.lm.max_cg_iterations);
    EXPECT_EQ(s.lm.initial_radius, t.lm.initial_radius);
    EXPECT_EQ(s.lm.max_radius, t.lm.max_radius);
    EXPECT_EQ(s.lm.linear_solver, t.lm.linear_solver);
    EXPECT_EQ(s.lm.iterations_per_batch, t.lm.iterations_per_batch);
    EXPECT_EQ(s.sampling.foreground_fraction, t.sampling.foreground_fraction);
    EXPECT_EQ(s.sampling.boundary_fraction, t.sampling.boundary_fraction);
    EXPECT_EQ(s.sampling.active_fraction, t.sampling.active_fraction);
    EXPECT_EQ(s.sampling.crop_scale, t.sampling.crop_scale);
    EXPECT_EQ(s.sampling.importance_depth, t.sampling.importance_depth);
    EXPECT_EQ(s.sampling.near_far_margin, t.sampling.near_far_margin);
    EXPECT_EQ(s.sampling.flow_gaps, t.sampling.flow_gaps);
    EXPECT_EQ(s.sampling.eikonal_points, t.sampling.eikonal_points);
    EXPECT_EQ(s.sampling.match_grid_points, t.sampling.match_grid_points);
    EXPECT_EQ(s.sampling.match_top_k, t.sampling.match_top_k);
    EXPECT_EQ(s.sampling.frames_per_batch, t.sampling.frames_per_batch);
    EXPECT_EQ(s.sampling.unbiased_silhouette, t.sampling.unbiased_silhouette);
    EXPECT_EQ(s.sampling.clip_to_box, t.sampling.clip_to_box);
    EXPECT_EQ(s.sampling.importance_samples, t.sampling.importance_samples);
    EXPECT_EQ(s.sampling.min_sdf_sample, t.sampling.min_sdf_sample);
    EXPECT_EQ(s.sampling.clip_margin, t.sampling.clip_margin);
    EXPECT_EQ(s.schedule.bone_reinit_at, t.schedule.bone_reinit_at);
    EXPECT_EQ(s.schedule.bone_reinit_keep_motion, t.schedule.bone_reinit_keep_motion);
    EXPECT_EQ(s.schedule.bone_sites, t.schedule.bone_sites);
    EXPECT_EQ(s.schedule.freeze_after_reinit, t.schedule.freeze_after_reinit);
    EXPECT_EQ(s.schedule.bounds_refresh_every, t.schedule.bounds_refresh_every);
    EXPECT_EQ(s.schedule.bounds_refresh_max_mask_loss, t.schedule.bounds_refresh_max_mask_loss);
    EXPECT_EQ(s.schedule.anneal_end_fraction, t.schedule.anneal_end_fraction);
    EXPECT_EQ(s.pose_solve.at, t.pose_solve.at);
    EXPECT_EQ(s.pose_solve.rays, t.pose_solve.rays);
    EXPECT_EQ(s.pose_solve.iterations, t.pose_solve.iterations);
    EXPECT_EQ(s.pose_solve.search_ratio, t.pose_solve.search_ratio);
    EXPECT_EQ(s.pose_solve.search_rotations, t.pose_solve.search_rotations);
    EXPECT_EQ(s.pose_solve.search_keep, t.pose_solve.search_keep);
    EXPECT_EQ(s.pose_solve.featureless_only, t.pose_solve.featureless_only);
    EXPECT_EQ(s.pose_solve.bones, t.pose_solve.bones);
    const BoneRegistrationConfig &r = s.bone_registration, &u = t.bone_registration;
    EXPECT_EQ(r.at, u.at);
    EXPECT_EQ(r.resolution, u.resolution);
    EXPECT_EQ(r.vertices, u.vertices);
    EXPECT_EQ(r.match_pixels, u.match_pixels);
    EXPECT_EQ(r.match_weight, u.match_weight);
    EXPECT_EQ(r.huber_px, u.huber_px);
    EXPECT_EQ(r.joint_weight, u.joint_weight);
    EXPECT_EQ(r.joint_min_weight, u.joint_min_weight);
    EXPECT_EQ(r.joint_points, u.joint_points);
    EXPECT_EQ(r.smooth_weight, u.smooth_weight);
    EXPECT_EQ(r.rest_weight, u.rest_weight);
    EXPECT_EQ(r.visible_tolerance, u.visible_tolerance);
    EXPECT_EQ(r.iterations, u.iterations);
    EXPECT_EQ(r.mask_weight, u.mask_weight);
    EXPECT_EQ(r.mask_points, u.mask_points);
    EXPECT_EQ(r.coverage_weight, u.coverage_weight);
    EXPECT_EQ(r.coverage_pixels, u.coverage_pixels);
    EXPECT_EQ(r.coverage_rounds, u.coverage_rounds);
    EXPECT_EQ(r.start, u.start);
    EXPECT_EQ(r.after_last_batch.match_weight, u.after_last_batch.match_weight);
    EXPECT_EQ(r.after_last_batch.mask_weight, u.after_last_batch.mask_weight);
    EXPECT_EQ(r.after_last_batch.coverage_weight, u.after_last_batch.coverage_weight);
    EXPECT_EQ(s.bone_steps_about_centres, t.bone_steps_about_centres);
    EXPECT_EQ(s.bone_steps_articulated, t.bone_steps_articulated);
    EXPECT_EQ(s.schedule.delta_skinning_from, t.schedule.delta_skinning_from);
    EXPECT_EQ(s.schedule.root_free_from, t.schedule.root_free_from);
    EXPECT_EQ(s.schedule.unbiased_silhouette_from, t.schedule.unbiased_silhouette_from);
    EXPECT_EQ(s.schedule.neus_from, t.schedule.neus_from);
    EXPECT_EQ(s.checkpoint_every, t.checkpoint_every);
    EXPECT_EQ(s.log_every, t.log_every);
  }
}

// Leaf paths and scalar values of a YAML tree.
void Leaves(const YAML::Node& node, const std::string& path,
            std::map<std::string, std::string>* out) {
  if (node.IsMap()) {
    for (auto it = node.begin(); it != node.end(); ++it) {
      Leaves(it->second, path + "." + it->first.Scalar(), out);
    }
  } else if (node.IsSequence()) {
    std::string joined;
    for (size_t i = 0; i < node.size(); ++i) {
      if (node[i].IsMap()) {
        Leaves(node[i], path + "[" + std::to_string(i) + "]", out);
      } else {
        joined += node[i].Scalar() + ",";
      }
    }
    if (node.size() == 0 || !node[0].IsMap()) (*out)[path] = "[" + joined + "]";
  } else {
    (*out)[path] = node.Scalar();
  }
}

TEST(SolverConfig, RoundTripKeepsEveryField) {
  const SolverConfig c = EveryFieldChanged();
  ASSERT_NO_THROW(CheckSolverConfig(c, "changed"));
  const std::string yaml = SolverConfigToYaml(c);
  const SolverConfig back = ParseSolverConfig(yaml, "resolved");
  ExpectSame(c, back);
  EXPECT_EQ(SolverConfigToYaml(back), yaml);

  // EveryFieldChanged really changes every written key (so ExpectSame above
  // covers every field the writer knows): compare with a default config of
  // the same shape, leaf by leaf.
  SolverConfig d;
  d.stages.resize(c.stages.size());
  std::map<std::string, std::string> changed, defaults;
  Leaves(YAML::Load(yaml), "", &changed);
  Leaves(YAML::Load(SolverConfigToYaml(d)), "", &defaults);
  EXPECT_EQ(changed.size(), defaults.size());
  EXPECT_GT(changed.size(), 100u);
  for (const auto& [key, value] : defaults) {
    ASSERT_TRUE(changed.count(key)) << key;
    // Must be true in a valid config; EveryConstraintNamesItsKey shows the
    // reader reads it (include_input: false fails the parse).
    if (key == ".model.field.position_encoding.include_input") continue;
    // EveryFieldChanged has delta skinning on, which excludes auto_size
    // (EveryConstraintNamesItsKey); AutoSizeRoundTrips covers the key.
    if (key == ".model.auto_size.enabled") continue;
    // The two bone-step keys exclude each other: stage 0 changes one,
    // stage 1 the other.
    if (key == ".stages[0].bone_steps_articulated" ||
        key == ".stages[1].bone_steps_about_centres") {
      continue;
    }
    EXPECT_NE(changed[key], value) << key << " unchanged by EveryFieldChanged";
  }
  // And the default config round-trips too.
  ExpectSame(d, ParseSolverConfig(SolverConfigToYaml(d), "defaults"));
}

// A registration after the last batch takes the weights that are set
// (`auto` in the resolved YAML: the registration's own).
TEST(SolverConfig, AfterLastBatchWeightsOverrideOnlyWhatIsSet) {
  const SolverConfig c = ParseSolverConfig(
      "stages:\n  - bone_registration: {at: [1.0], match_weight: 8, mask_weight: 4, "
      "coverage_weight: 6, after_last_batch: {mask_weight: 40}}\n",
      "t.yaml");
  const BoneRegistrationConfig& reg = c.stages[0].bone_registration;
  const BoneRegistrationConfig last = reg.AfterLastBatch();
  EXPECT_EQ(last.mask_weight, 40.0);
  EXPECT_EQ(last.match_weight, 8.0);
  EXPECT_EQ(last.coverage_weight, 6.0);
  EXPECT_EQ(last.at, reg.at);
  EXPECT_EQ(reg.mask_weight, 4.0);  // the other registrations keep their own
  const std::string yaml = SolverConfigToYaml(c);
  EXPECT_NE(yaml.find("after_last_batch: {match_weight: auto, mask_weight: 40, "
                      "coverage_weight: auto}"),
            std::string::npos)
      << yaml;
  const SolverConfig back = ParseSolverConfig(yaml, "resolved");
  EXPECT_EQ(back.stages[0].bone_registration.after_last_batch.mask_weight, 40.0);
  EXPECT_FALSE(back.stages[0].bone_registration.after_last_batch.match_weight.has_value());
  EXPECT_THROW(ParseSolverConfig("stages:\n  - bone_registration: {after_last_batch: "
                                 "{mask: 3}}\n",
                                 "t.yaml"),
               InputError);
}

// model.auto_size: read, checked, written and read back; the delta-skinning
// conflict says why.
TEST(SolverConfig, AutoSizeRoundTrips) {
  const SolverConfig c = ParseSolverConfig(
      "model:\n  num_bones: 4\n  auto_size: {enabled: true, max_bones: 16, grow_at: [0.5], "
      "error_ratio: 2, eval_rays: 512, max_width: 128}\nstages: [{}]\n",
      "test.yaml");
  EXPECT_TRUE(c.model.auto_size.enabled);
  EXPECT_EQ(c.model.auto_size.max_bones, 16);
  EXPECT_EQ(c.model.auto_size.grow_at, std::vector<double>{0.5});
  EXPECT_EQ(c.model.auto_size.error_ratio, 2.0);
  EXPECT_EQ(c.model.auto_size.eval_rays, 512);
  EXPECT_EQ(c.model.auto_size.max_width, 128);
  const std::string yaml = SolverConfigToYaml(c);
  EXPECT_NE(yaml.find("auto_size:"), std::string::npos) << yaml;
  ExpectSame(c, ParseSolverConfig(yaml, "resolved"));
  // Defaults.
  const AutoSizeOptions d = ParseSolverConfig(kMinimal, "test.yaml").model.auto_size;
  EXPECT_FALSE(d.enabled);
  EXPECT_EQ(d.max_bones, 32);
  EXPECT_EQ(d.grow_at, (std::vector<double>{0.4, 0.55, 0.7}));
  EXPECT_EQ(d.error_ratio, 1.5);
  EXPECT_EQ(d.eval_rays, 2048);
  EXPECT_EQ(d.max_width, 0);
  // A disabled block does not constrain the model (64 bones > max_bones 32).
  EXPECT_NO_THROW(ParseSolverConfig("model: {num_bones: 64}\nstages: [{}]\n", "test.yaml"));
  // With delta skinning: an error naming the key and the reason.
  const std::string message = ParseError(
      "model:\n  delta_skinning: {enabled: true}\n  auto_size:\n    enabled: true\n"
      "stages: [{}]\n");
  EXPECT_EQ(message.rfind("test.yaml: model.auto_size.enabled: ", 0), 0u) << message;
  EXPECT_NE(message.find("MLP_Delta"), std::string::npos) << message;
  EXPECT_NE(message.find("(line 4)"), std::string::npos) << message;
}

TEST(SolverConfig, ResolvedYamlIsReadable) {
  const std::string yaml = SolverConfigToYaml(ParseSolverConfig(
      "stages: [{adam: {lr: 0.0005}, sampling: {flow_gaps: [1, 2]}}]\n", "test.yaml"));
  // Short decimals, flow lists, enum words.
  EXPECT_NE(yaml.find("lr: 0.0005\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("flow_gaps: [1, 2]"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("activation: softplus"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("include_input: true"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("scene_scale: auto\n"), std::string::npos) << yaml;
}

// model.scene_scale: the word auto (the default, empty optional) or a
// finite number > 0; anything else names the key.
TEST(SolverConfig, SceneScaleIsAutoOrAPositiveNumber) {
  EXPECT_FALSE(ParseSolverConfig(kMinimal, "test.yaml").model.scene_scale.has_value());
  EXPECT_FALSE(ParseSolverConfig("model: {scene_scale: auto}\nstages: [{}]\n", "test.yaml")
                   .model.scene_scale.has_value());
  const SolverConfig fixed =
      ParseSolverConfig("model: {scene_scale: 0.01}\nstages: [{}]\n", "test.yaml");
  ASSERT_TRUE(fixed.model.scene_scale.has_value());
  EXPECT_EQ(*fixed.model.scene_scale, 0.01);
  EXPECT_NE(SolverConfigToYaml(fixed).find("scene_scale: 0.01\n"), std::string::npos);
  EXPECT_EQ(*ParseSolverConfig("model: {scene_scale: 1e3}\nstages: [{}]\n", "test.yaml")
                 .model.scene_scale,
            1000.0);

  // Not a number (and not auto): a type error naming the key and its line.
  for (const char* value : {"big", "Auto", "[1]", ".inf", ""}) {
    const std::string message =
        ParseError("stages: [{}]\nmodel:\n  scene_scale: " + std::string(value) + "\n");
    EXPECT_EQ(message.rfind("test.yaml: key 'model.scene_scale' (line ", 0), 0u)
        << value << ": " << message;
    EXPECT_NE(message.find("): expected auto or a finite number > 0, got "), std::string::npos)
        << value << ": " << message;
  }
  // A number <= 0: the constraint, with the line.
  EXPECT_EQ(ParseError("stages: [{}]\nmodel:\n  scene_scale: -1\n"),
            "test.yaml: model.scene_scale: expected auto or a finite number > 0, got -1 (line 3)");
  EXPECT_EQ(ParseError("stages: [{}]\nmodel:\n  scene_scale: 0\n"),
            "test.yaml: model.scene_scale: expected auto or a finite number > 0, got 0 (line 3)");
}

// docs/config.md: its YAML examples parse, and every key of the resolved
// config is documented there (as `key`).
TEST(SolverConfig, DocsExamplesParseAndEveryKeyIsDocumented) {
  std::ifstream in(std::string(BANMO_SOURCE_DIR) + "/docs/config.md");
  ASSERT_TRUE(in.good());
  std::stringstream text;
  text << in.rdbuf();
  const std::string doc = text.str();
  int examples = 0;
  for (size_t pos = doc.find("```yaml\n"); pos != std::string::npos;
       pos = doc.find("```yaml\n", pos + 1)) {
    const size_t begin = pos + 8;
    const size_t end = doc.find("```", begin);
    ASSERT_NE(end, std::string::npos);
    const std::string yaml = doc.substr(begin, end - begin);
    EXPECT_NO_THROW(ParseSolverConfig(yaml, "docs example")) << yaml;
    ++examples;
  }
  EXPECT_GE(examples, 3);

  SolverConfig c;
  c.stages.resize(1);
  std::map<std::string, std::string> leaves;
  Leaves(YAML::Load(SolverConfigToYaml(c)), "", &leaves);
  for (const auto& entry : leaves) {
    const std::string& path = entry.first;
    const std::string key = path.substr(path.find_last_of(".]") + 1);
    // Loss terms are documented as `<term>.weight` etc. plus the term names.
    const bool documented = doc.find("`" + key + "`") != std::string::npos ||
                            doc.find("." + key + "`") != std::string::npos;
    EXPECT_TRUE(documented) << key << " (" << path << ")";
  }
}

}  // namespace
}  // namespace banmo

namespace banmo {
namespace {

// The config's loss keys and default weights are the loss table's.
TEST(SolverConfig, LossKeysAndDefaultsComeFromTheTable) {
  const LossesConfig defaults;
  for (const LossTermInfo& info : kLossTable) {
    EXPECT_EQ(defaults[info.term].weight, info.default_weight) << info.key;
    const SolverConfig c = ParseSolverConfig(
        std::string("stages:\n  - losses: {") + info.key + ": {weight: 0.25}}\n", "t.yaml");
    EXPECT_EQ(c.stages[0].losses[info.term].weight, 0.25) << info.key;
    EXPECT_NE(SolverConfigToYaml(c).find(std::string(info.key) + ":"), std::string::npos);
  }
  const RayLossWeights ray = defaults.RayWeights();
  for (LossTerm term : RayTerms()) EXPECT_EQ(ray[term], LossInfo(term).default_weight);
}

}  // namespace
}  // namespace banmo

namespace banmo {
namespace {

// Typed options: an unknown name is refused where it is read, naming the key,
// the choices and the line.
TEST(SolverConfig, UnknownOptionNamesListTheChoices) {
  const std::pair<std::string, std::string> cases[] = {
      {"stages:\n  - step_rule: sgd\n",
       "t.yaml: stages[0].step_rule: expected one of {adam, lm, alternate}, got 'sgd' (line 2)"},
      {"stages:\n  - adam: {schedule: cosine}\n",
       "t.yaml: stages[0].adam.schedule: expected one of {onecycle, constant}, got 'cosine' "
       "(line 2)"},
      {"stages:\n  - lm: {linear_solver: dense}\n",
       "t.yaml: stages[0].lm.linear_solver: expected one of {cgnr, iterative_schur}, got 'dense' "
       "(line 2)"},
      {"stages:\n  - losses:\n      flow: {robust: {type: l1}}\n",
       "t.yaml: stages[0].losses.flow.robust.type: expected one of {none, huber, cauchy, soft_l1, "
       "arctan, tolerant}, got 'l1' (line 3)"},
      {"stages:\n  - bone_registration: {at: [0.5], start: next}\n",
       "t.yaml: stages[0].bone_registration.start: expected one of {previous, own, lower_cost}, "
       "got 'next' (line 2)"},
      {"model: {density: nerf}\nstages: [{}]\n",
       "t.yaml: model.density: expected one of {volsdf, neus}, got 'nerf' (line 1)"},
      {"defaults:\n  step_rule: [adam]\nstages: [{}]\n",
       "t.yaml: defaults.step_rule: expected one of {adam, lm, alternate}, got a list (line 2)"},
  };
  for (const auto& [yaml, expected] : cases) {
    std::string message;
    try {
      ParseSolverConfig(yaml, "t.yaml");
    } catch (const InputError& e) {
      message = e.what();
    }
    EXPECT_EQ(message, expected) << yaml;
  }
}

TEST(SolverConfig, OptionNamesRoundTrip) {
  SolverConfig c = ParseSolverConfig(
      "stages:\n  - step_rule: alternate\n    pose_solve: {every: 10}\n"
      "    lm: {linear_solver: iterative_schur}\n"
      "    adam: {schedule: constant}\n    constant: [bones_t, pose_code]\n"
      "    losses: {rgb: {robust: {type: soft_l1}}}\n",
      "t.yaml");
  const StageConfig& s = c.stages[0];
  EXPECT_EQ(s.step_rule, StepRule::kAlternate);
  EXPECT_EQ(s.lm.linear_solver, LinearSolverType::kIterativeSchur);
  EXPECT_EQ(s.adam.schedule, LrSchedule::kConstant);
  EXPECT_EQ(s.constant,
            (std::vector<ParameterGroup>{ParameterGroup::kBonesT, ParameterGroup::kPoseCode}));
  EXPECT_EQ(s.losses[LossTerm::kRgb].robust.type, RobustLossType::kSoftL1);
  const std::string yaml = SolverConfigToYaml(c);
  EXPECT_NE(yaml.find("step_rule: alternate"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("constant: [bones_t, pose_code]"), std::string::npos) << yaml;
  EXPECT_EQ(SolverConfigToYaml(ParseSolverConfig(yaml, "again.yaml")), yaml);
}

// schedule.unbiased_silhouette_from switches the silhouette weighting on at
// a fraction of the stage; sampling.unbiased_silhouette means from the start.
TEST(SolverConfig, SamplingAtSwitchesTheSilhouetteWeightingOn) {
  StageConfig stage;
  EXPECT_FALSE(SamplingAt(stage, 0.0).unbiased_silhouette);
  EXPECT_FALSE(SamplingAt(stage, 1.0).unbiased_silhouette);  // default 1: never in the stage
  stage.schedule.unbiased_silhouette_from = 0.3;
  EXPECT_FALSE(SamplingAt(stage, 0.0).unbiased_silhouette);
  EXPECT_FALSE(SamplingAt(stage, 0.29).unbiased_silhouette);
  EXPECT_TRUE(SamplingAt(stage, 0.3).unbiased_silhouette);
  EXPECT_TRUE(SamplingAt(stage, 0.9).unbiased_silhouette);
  stage.sampling.unbiased_silhouette = true;
  EXPECT_TRUE(SamplingAt(stage, 0.0).unbiased_silhouette);
  // Nothing else of the sampling changes.
  stage.sampling.frames_per_batch = 7;
  stage.sampling.foreground_fraction = 0.4;
  EXPECT_EQ(SamplingAt(stage, 0.5).frames_per_batch, 7);
  EXPECT_EQ(SamplingAt(stage, 0.5).foreground_fraction, 0.4);
}

}  // namespace
}  // namespace banmo
