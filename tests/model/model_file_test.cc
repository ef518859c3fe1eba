#include "banmo/model/model_file.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/util/error.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

// A model small enough to write in microseconds.
ModelOptions SmallOptions() {
  ModelOptions o;
  o.num_bones = 3;
  o.field.position_encoding.num_bands = 2;
  o.field.sdf_width = 8;
  o.field.sdf_layers = 2;
  o.field.geometry_feature_dim = 4;
  o.field.color_width = 8;
  o.field.color_layers = 1;
  o.field.embedding_width = 8;
  o.field.embedding_layers = 1;
  o.field.appearance_code_dim = 2;
  o.seed = 5;
  return o;
}

std::unique_ptr<Model> SmallModel(const ModelOptions& options) {
  PinholeCamera a, b;
  a.width = 32;
  a.height = 24;
  a.intrinsics = Eigen::Vector4d(40.5, 41.25, 16.0, 12.0);
  b.width = 20;
  b.height = 20;
  b.intrinsics = Eigen::Vector4d(1.0 / 3.0, 30.0, 10.0, 9.5);
  auto model =
      std::make_unique<Model>(options, std::vector<int>{2, 3}, std::vector<PinholeCamera>{a, b});
  // Every block filled with distinct values, so a permutation would show.
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  model->ForEachBlock([&](const std::string&, double* data, int size) {
    for (int i = 0; i < size; ++i) data[i] = normal(rng);
  });
  return model;
}

std::vector<double> AllParameters(const Model& model) {
  std::vector<double> out;
  model.ForEachBlock(
      [&](const std::string&, const double* d, int n) { out.insert(out.end(), d, d + n); });
  return out;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The message of the InputError thrown by LoadModel(dir) ("" if none).
std::string LoadError(const fs::path& dir) {
  try {
    LoadModel(dir.string());
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// `model` holds the doubles of `params` (a params.bin whose root corrections
// were camera-side, G = dG_cam G0): every block bitwise, except root_delta,
// whose root pose G0 dG equals dG_cam G0 to 1e-14 (a few roundings of unit
// quaternions and O(1) translations).
void ExpectParamsWithCameraSideCorrections(const Model& model, const std::string& params) {
  const std::vector<double> values = AllParameters(model);
  ASSERT_EQ(params.size(), 16 + sizeof(double) * values.size());
  std::vector<double> raw(values.size());
  std::memcpy(raw.data(), params.data() + 16, sizeof(double) * raw.size());
  size_t at = 0;
  int corrections = 0;
  model.ForEachBlock([&](const std::string& name, const double* data, int size) {
    const double* old = raw.data() + at;
    at += size;
    if (name.find("/root_delta") == std::string::npos) {
      EXPECT_EQ(std::vector<double>(data, data + size), std::vector<double>(old, old + size))
          << name;
      return;
    }
    const double* init = data + kPoseSize;  // root_init follows root_delta
    Pose camera_side, object_side;
    PoseCompose(old, init, camera_side.data());
    PoseCompose(init, data, object_side.data());
    EXPECT_LT((camera_side - object_side).cwiseAbs().maxCoeff(), 1e-14) << name;
    ++corrections;
  });
  int frames = 0;
  for (int v = 0; v < model.num_videos(); ++v) frames += model.video(v).frames.size();
  EXPECT_EQ(corrections, frames) << "root_delta blocks";
}

void ExpectSameModel(const Model& a, const Model& b) {
  EXPECT_EQ(AllParameters(a), AllParameters(b));
  EXPECT_EQ(a.scene_scale(), b.scene_scale());
  EXPECT_EQ(a.num_bones(), b.num_bones());
  EXPECT_EQ(a.options().field.sdf_width, b.options().field.sdf_width);
  EXPECT_EQ(a.options().field.color_width, b.options().field.color_width);
  EXPECT_EQ(a.options().seed, b.options().seed);
  EXPECT_EQ(a.options().scene_scale, b.options().scene_scale);
  ASSERT_EQ(a.num_videos(), b.num_videos());
  for (int v = 0; v < a.num_videos(); ++v) {
    EXPECT_EQ(a.video(v).frames.size(), b.video(v).frames.size());
    EXPECT_EQ(a.video(v).camera.width, b.video(v).camera.width);
    EXPECT_EQ(a.video(v).camera.height, b.video(v).camera.height);
    EXPECT_EQ(a.video(v).camera.intrinsics, b.video(v).camera.intrinsics);
  }
}

TEST(ModelFile, RoundTripIsBitwise) {
  ModelOptions options = SmallOptions();
  options.init_beta = 0.1 / 3.0;  // not a short decimal
  options.density = DensityModel::kNeus;
  options.auto_size.grow_at = {0.25, 0.5};
  options.delta_skinning.enabled = true;
  options.delta_skinning.width = 8;
  options.delta_skinning.hidden_layers = 1;
  options.delta_skinning.pose_code_dim = 3;
  const std::unique_ptr<Model> model = SmallModel(options);
  model->set_scene_scale(0.25);
  const fs::path dir = FreshDir("banmo_model_file_round_trip");
  WriteModelFiles(dir.string(), *model);
  const std::unique_ptr<Model> back = LoadModel(dir.string());
  ExpectSameModel(*model, *back);
  EXPECT_TRUE(back->has_delta_skinning());
  EXPECT_EQ(back->options().init_beta, options.init_beta);
  EXPECT_EQ(back->options().density, DensityModel::kNeus);
  EXPECT_EQ(back->options().auto_size.grow_at, options.auto_size.grow_at);
  EXPECT_EQ(back->options().delta_skinning.pose_code_dim, 3);
  // Not recorded: stays not recorded.
  EXPECT_FALSE(back->canonical_bounds().has_value());
  EXPECT_FALSE(back->training_sampling().has_value());
}

TEST(ModelFile, KeepsTheSizesAfterAGrowStep) {
  const std::unique_ptr<Model> model = SmallModel(SmallOptions());
  std::vector<double> bones(static_cast<size_t>(kBoneSize) * 5, 0.0);
  std::copy(model->bones(), model->bones() + model->bones_size(), bones.begin());
  for (int b = 3; b < 5; ++b) bones[kBoneSize * b + kBoneSize - 1] = 0.1;  // any valid values
  model->SetBones(5, bones);
  const fs::path dir = FreshDir("banmo_model_file_sizes");
  WriteModelFiles(dir.string(), *model);
  const std::unique_ptr<Model> back = LoadModel(dir.string());
  EXPECT_EQ(back->num_bones(), 5);
  ExpectSameModel(*model, *back);
}

TEST(ModelFile, StoresTheCanonicalBoundsAndTrainingSampling) {
  const std::unique_ptr<Model> model = SmallModel(SmallOptions());
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d(-0.7, -1.0 / 3.0, -0.9),
                                   Eigen::Vector3d(0.8, 0.6, 0.1 / 7.0));
  model->set_canonical_bounds(bounds);
  model->set_training_sampling(TrainingSampling{24, 0.15, true});
  const fs::path dir = FreshDir("banmo_model_file_bounds");
  WriteModelFiles(dir.string(), *model);
  const std::unique_ptr<Model> back = LoadModel(dir.string());
  ASSERT_TRUE(back->canonical_bounds().has_value());
  EXPECT_EQ(back->canonical_bounds()->min(), bounds.min());  // exact: FormatDouble round-trips
  EXPECT_EQ(back->canonical_bounds()->max(), bounds.max());
  ASSERT_TRUE(back->training_sampling().has_value());
  EXPECT_EQ(back->training_sampling()->samples_per_ray, 24);
  EXPECT_EQ(back->training_sampling()->near_far_margin, 0.15);
  EXPECT_TRUE(back->training_sampling()->importance_depth);
  EXPECT_FALSE(back->training_sampling()->clip_to_box);  // not written when off
  EXPECT_EQ(ReadText(dir / "model.yaml").find("clip_to_box"), std::string::npos);
  EXPECT_EQ(back->training_sampling()->importance_samples, 0);
  EXPECT_EQ(ReadText(dir / "model.yaml").find("importance_samples"), std::string::npos);
  ExpectSameModel(*model, *back);
  // Ray clipping is recorded when on.
  model->set_training_sampling(TrainingSampling{24, 0.15, true, true, 0.125});
  WriteModelFiles(dir.string(), *model);
  const std::unique_ptr<Model> clipped = LoadModel(dir.string());
  ASSERT_TRUE(clipped->training_sampling().has_value());
  EXPECT_TRUE(clipped->training_sampling()->clip_to_box);
  EXPECT_EQ(clipped->training_sampling()->clip_margin, 0.125);
  // So are the importance pass's added samples.
  model->set_training_sampling(TrainingSampling{24, 0.15, true, false, 0.1, 40});
  WriteModelFiles(dir.string(), *model);
  EXPECT_EQ(LoadModel(dir.string())->training_sampling()->importance_samples, 40);
  EXPECT_FALSE(LoadModel(dir.string())->training_sampling()->min_sdf_sample);
  EXPECT_EQ(ReadText(dir / "model.yaml").find("min_sdf_sample"), std::string::npos);
  // And the sample at the SDF minimum.
  model->set_training_sampling(TrainingSampling{24, 0.15, true, false, 0.1, 0, true});
  WriteModelFiles(dir.string(), *model);
  EXPECT_TRUE(LoadModel(dir.string())->training_sampling()->min_sdf_sample);
  model->set_training_sampling(TrainingSampling{24, 0.15, true, true, 0.125});
  WriteModelFiles(dir.string(), *model);
  // A negative clip margin in the file is an error naming the key.
  std::string yaml_clip = ReadText(dir / "model.yaml");
  const size_t margin_at = yaml_clip.find("clip_margin: ");
  ASSERT_NE(margin_at, std::string::npos) << yaml_clip;
  yaml_clip.insert(margin_at + std::string("clip_margin: ").size(), "-");
  std::ofstream(dir / "model.yaml") << yaml_clip;
  EXPECT_NE(LoadError(dir).find("clip_margin >= 0"), std::string::npos) << LoadError(dir);
  WriteModelFiles(dir.string(), *model);

  // A box without its max, or with max <= min, is an error naming the key.
  const std::string yaml = ReadText(dir / "model.yaml");
  const size_t max_line = yaml.find("  max: ");
  ASSERT_NE(max_line, std::string::npos) << yaml;
  std::string no_max = yaml;
  no_max.erase(max_line, yaml.find('\n', max_line) + 1 - max_line);
  std::ofstream(dir / "model.yaml") << no_max;
  EXPECT_NE(LoadError(dir).find("missing key 'canonical_bounds.max'"), std::string::npos)
      << LoadError(dir);
  model->set_canonical_bounds(
      Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 1)));
  WriteModelFiles(dir.string(), *model);
  EXPECT_NE(LoadError(dir).find("max > min on every axis"), std::string::npos) << LoadError(dir);
}

TEST(ModelFile, FallsBackToTheOldFolderOfAnInterruptedSave) {
  const std::unique_ptr<Model> model = SmallModel(SmallOptions());
  const fs::path dir = FreshDir("banmo_model_file_old");
  fs::create_directories(dir / "m.old");
  WriteModelFiles((dir / "m.old").string(), *model);
  EXPECT_EQ(ResolveModelFolder((dir / "m").string()), (dir / "m.old").string());
  ExpectSameModel(*model, *LoadModel((dir / "m").string()));
}

// A checkpoint folder written by the code before the model file existed
// (format banmo-checkpoint-1; how it was made: data/README.md).
TEST(ModelFile, LoadsACheckpointOfThePreviousFormat) {
  const std::string dir = std::string(BANMO_MODEL_TEST_DATA) + "/checkpoint_v1";
  const std::unique_ptr<Model> model = LoadModel(dir);
  // The sizes of its config (data/README.md).
  EXPECT_EQ(model->num_bones(), 2);
  EXPECT_EQ(model->options().field.sdf_width, 8);
  EXPECT_EQ(model->options().field.color_width, 8);
  EXPECT_EQ(model->options().field.appearance_code_dim, 2);
  EXPECT_EQ(model->num_videos(), 1);
  EXPECT_EQ(model->video(0).frames.size(), 2u);
  EXPECT_EQ(model->video(0).camera.width, 16);
  EXPECT_GT(model->scene_scale(), 0.0);
  EXPECT_FALSE(model->canonical_bounds().has_value());         // not recorded then
  EXPECT_EQ(model->options().density, DensityModel::kVolSdf);  // the only density then
  // Its training sampling is the last stage of its config.
  ASSERT_TRUE(model->training_sampling().has_value());
  EXPECT_EQ(model->training_sampling()->samples_per_ray, 8);
  EXPECT_EQ(model->training_sampling()->near_far_margin, 0.2);
  EXPECT_FALSE(model->training_sampling()->importance_depth);
  // The parameters are params.bin's doubles in ForEachBlock order, the root
  // corrections re-expressed on the object side.
  ExpectParamsWithCameraSideCorrections(*model, ReadText(dir + "/params.bin"));

  // Written again, it reads back the same in the current format.
  const fs::path copy = FreshDir("banmo_model_file_from_v1");
  WriteModelFiles(copy.string(), *model);
  EXPECT_NE(ReadText(copy / "model.yaml").find(kModelFileFormat), std::string::npos);
  ExpectSameModel(*model, *LoadModel(copy.string()));
}

// A copy of the previous-format fixture whose model.yaml can be edited.
fs::path CopyOfV1(const std::string& name) {
  const fs::path dir = FreshDir(name);
  for (const char* file : {"model.yaml", "params.bin"}) {
    fs::copy_file(fs::path(BANMO_MODEL_TEST_DATA) / "checkpoint_v1" / file, dir / file);
  }
  return dir;
}

void ReplaceOnce(std::string* text, const std::string& from, const std::string& to) {
  const size_t at = text->find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text->replace(at, from.size(), to);
}

// A model-2 folder written before `root_correction` existed stored
// camera-side corrections; it loads with the same root poses.
TEST(ModelFile, FolderWithoutRootCorrectionKeyLoadsTheSameRootPoses) {
  const std::unique_ptr<Model> model = SmallModel(SmallOptions());
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  for (int v = 0; v < model->num_videos(); ++v) {
    for (FrameParameters& f : model->video(v).frames) {
      f.root_init = PoseFromAngleAxis(Eigen::Vector3d(normal(rng), normal(rng), normal(rng)),
                                      Eigen::Vector3d(normal(rng), normal(rng), 3.0));
      f.root_delta = PoseFromAngleAxis(0.5 * Eigen::Vector3d(normal(rng), normal(rng), 0.0),
                                       Eigen::Vector3d(normal(rng), 0.0, normal(rng)));
    }
  }
  const fs::path dir = FreshDir("banmo_model_file_camera_side");
  WriteModelFiles(dir.string(), *model);
  std::string yaml = ReadText(dir / "model.yaml");
  ReplaceOnce(&yaml, "root_correction: object\n", "");
  std::ofstream(dir / "model.yaml") << yaml;
  ExpectParamsWithCameraSideCorrections(*LoadModel(dir.string()), ReadText(dir / "params.bin"));

  ReplaceOnce(&yaml, "videos:", "root_correction: sideways\nvideos:");
  std::ofstream(dir / "model.yaml") << yaml;
  const std::string error = LoadError(dir);
  EXPECT_NE(error.find("model.yaml"), std::string::npos) << error;
  EXPECT_NE(error.find("root_correction"), std::string::npos) << error;
  EXPECT_NE(error.find("sideways"), std::string::npos) << error;
}

TEST(ModelFile, PreviousFormatWithoutSceneScaleLoadsWithOne) {
  const fs::path dir = CopyOfV1("banmo_model_file_v1_scale");
  const std::string yaml = ReadText(dir / "model.yaml");
  std::string scaled = yaml;
  ReplaceOnce(&scaled, "scene_scale: 1\n", "scene_scale: 4\n");
  std::ofstream(dir / "model.yaml") << scaled;
  EXPECT_EQ(LoadModel(dir.string())->scene_scale(), 4.0);
  std::string unscaled = yaml;
  ReplaceOnce(&unscaled, "scene_scale: 1\n", "");
  std::ofstream(dir / "model.yaml") << unscaled;
  EXPECT_EQ(LoadModel(dir.string())->scene_scale(), 1.0);
}

TEST(ModelFile, PreviousFormatModelSizeErrorsNameTheFileAndKey) {
  const fs::path dir = CopyOfV1("banmo_model_file_v1_size");
  const std::string yaml = ReadText(dir / "model.yaml");
  for (const auto& [text, expected] : std::vector<std::pair<std::string, std::string>>{
           {"many", "num_bones"}, {"-3", "model.num_bones"}}) {
    std::string broken = yaml;
    ReplaceOnce(&broken, "model_size: {num_bones: 2,", "model_size: {num_bones: " + text + ",");
    std::ofstream(dir / "model.yaml") << broken;
    const std::string message = LoadError(dir);
    EXPECT_NE(message.find((dir / "model.yaml").string()), std::string::npos) << message;
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  }
  // Without model_size, the config's sizes (the same here).
  std::string unsized = yaml;
  ReplaceOnce(&unsized, "model_size: {num_bones: 2, sdf_width: 8, color_width: 8}\n", "");
  std::ofstream(dir / "model.yaml") << unsized;
  EXPECT_EQ(LoadModel(dir.string())->num_bones(), 2);
}

TEST(ModelFile, UnknownFormatNamesTheFileAndWhatToDo) {
  const fs::path dir = FreshDir("banmo_model_file_unknown");
  WriteModelFiles(dir.string(), *SmallModel(SmallOptions()));
  std::string yaml = ReadText(dir / "model.yaml");
  yaml.replace(yaml.find(kModelFileFormat), std::strlen(kModelFileFormat), "banmo-model-9");
  std::ofstream(dir / "model.yaml") << yaml;
  const std::string message = LoadError(dir);
  EXPECT_NE(message.find((dir / "model.yaml").string()), std::string::npos) << message;
  EXPECT_NE(message.find("unknown model format 'banmo-model-9'"), std::string::npos) << message;
  EXPECT_NE(message.find("solve again"), std::string::npos) << message;
}

TEST(ModelFile, CorruptFilesNameTheFileAndWhatToDo) {
  const fs::path dir = FreshDir("banmo_model_file_corrupt");
  WriteModelFiles(dir.string(), *SmallModel(SmallOptions()));
  const std::string yaml = ReadText(dir / "model.yaml");
  const std::string params = ReadText(dir / "params.bin");
  struct Case {
    std::string what;
    std::string file;  // model.yaml or params.bin
    std::string contents;
    std::string expected;  // part of the message
  };
  std::string bad_width = yaml;
  bad_width.replace(bad_width.find("sdf_width: 8"), 12, "sdf_width: wide");
  std::string no_format = yaml;
  no_format.erase(0, no_format.find('\n') + 1);
  const std::vector<Case> cases = {
      {"truncated parameters", "params.bin", params.substr(0, 100), "holds"},
      {"not a parameter file", "params.bin", "hello", "not a banmo parameter file"},
      {"not YAML", "model.yaml", "format: [unclosed", "invalid YAML"},
      {"no format", "model.yaml", no_format, "missing key 'format'"},
      {"bad option", "model.yaml", bad_width, "options.field.sdf_width"},
  };
  for (const Case& c : cases) {
    WriteModelFiles(dir.string(), *SmallModel(SmallOptions()));
    std::ofstream(dir / c.file, std::ios::binary) << c.contents;
    const std::string message = LoadError(dir);
    EXPECT_NE(message.find((dir / c.file).string()), std::string::npos)
        << c.what << ": " << message;
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.what << ": " << message;
    EXPECT_NE(message.find("solve again"), std::string::npos) << c.what << ": " << message;
  }
  const std::string missing = LoadError(dir / "nonexistent");
  EXPECT_NE(missing.find("nonexistent: not a model folder"), std::string::npos) << missing;
}

// Sizes in model.yaml beyond the documented limits (docs/robustness.md)
// are refused naming the file and key, before the model is allocated (a
// num_bands of 32769 once grew to 6-7 GB and ended in std::bad_alloc).
TEST(ModelFile, SizesBeyondTheLimitsAreRefusedByFileAndKey) {
  const std::unique_ptr<Model> model = SmallModel(SmallOptions());
  model->set_training_sampling(TrainingSampling{24, 0.15, true});
  const fs::path dir = FreshDir("banmo_model_file_limits");
  WriteModelFiles(dir.string(), *model);
  const std::string yaml = ReadText(dir / "model.yaml");
  auto replaced = [&](const std::string& from, const std::string& to) {
    const size_t at = yaml.find(from);
    EXPECT_NE(at, std::string::npos) << from << " not in " << yaml;
    std::string t = yaml;
    if (at != std::string::npos) t.replace(at, from.size(), to);
    return t;
  };
  const struct {
    std::string from, to, expect;
  } cases[] = {
      {"num_bands: " + std::to_string(SmallOptions().field.position_encoding.num_bands),
       "num_bands: 32769", "model.field.position_encoding.num_bands must be in [0, 32], got 32769"},
      {"sdf_width: " + std::to_string(SmallOptions().field.sdf_width), "sdf_width: 100000",
       "model.field.sdf_width must be in [1, 4096], got 100000"},
      {"samples_per_ray: 24", "samples_per_ray: 100000", "samples_per_ray in [1, 1024]"},
      {"frames: 2", "frames: 2000000000", "frames in [0, 100000]"},
  };
  for (const auto& c : cases) {
    std::ofstream(dir / "model.yaml") << replaced(c.from, c.to);
    const std::string error = LoadError(dir);
    EXPECT_NE(error.find((dir / "model.yaml").string()), std::string::npos) << error;
    EXPECT_NE(error.find(c.expect), std::string::npos) << c.to << ": " << error;
  }
}

// A model folder (or its model.yaml) that is a symbolic link loop: an
// error naming it (std::filesystem::exists threw: exit 3).
TEST(ModelFile, SymlinkLoopsAreNamed) {
  const fs::path dir = FreshDir("banmo_model_file_loop");
  fs::create_symlink(dir / "b", dir / "a");
  fs::create_symlink(dir / "a", dir / "b");
  std::string error = LoadError(dir / "a");
  EXPECT_NE(error.find("Too many levels of symbolic links"), std::string::npos) << error;
  fs::create_directories(dir / "m");
  fs::create_symlink("model.yaml", dir / "m" / "model.yaml");
  error = LoadError(dir / "m");
  EXPECT_NE(error.find((dir / "m" / "model.yaml").string() + ": cannot open file (Too many levels"),
            std::string::npos)
      << error;
}

}  // namespace
}  // namespace banmo
