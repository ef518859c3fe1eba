#include "banmo/optim/checkpoint.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/model/model_file.h"
#include "banmo/util/error.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<double> AllParameters(const Model& model) {
  std::vector<double> out;
  model.ForEachBlock(
      [&](const std::string&, const double* d, int n) { out.insert(out.end(), d, d + n); });
  return out;
}

// The checkpoint of the previous format (written by the code before the
// model file existed: tests/model/data/README.md).
const std::string kV1 = std::string(BANMO_SOURCE_DIR) + "/tests/model/data/checkpoint_v1";

TEST(Checkpoint, PreviousFormatLoadsWithItsInfo) {
  CheckpointInfo info;
  std::string state = "not read";
  const std::unique_ptr<Model> model = LoadCheckpoint(kV1, &info, &state);
  EXPECT_EQ(info.stage, 1);  // written at the end of its only stage
  EXPECT_EQ(info.batch, 0);
  EXPECT_NE(info.config.find("samples_per_ray: 8"), std::string::npos) << info.config;
  EXPECT_EQ(state, "");  // the fixture keeps no solver state
  EXPECT_EQ(AllParameters(*model), AllParameters(*LoadModel(kV1)));
}

TEST(Checkpoint, RoundTripWritesAModelFolderPlusTheSolverFiles) {
  const std::unique_ptr<Model> model = LoadModel(kV1);
  model->set_canonical_bounds(
      Eigen::AlignedBox3d(Eigen::Vector3d(-1, -0.5, -0.25), Eigen::Vector3d(0.5, 1, 2)));
  const fs::path dir = fs::path(::testing::TempDir()) / "banmo_checkpoint_round_trip";
  fs::remove_all(dir);
  SaveCheckpoint(dir.string(), *model, CheckpointInfo{2, 9, "seed: 1\n"}, "bytes");
  EXPECT_TRUE(fs::exists(dir / "checkpoint.yaml"));
  EXPECT_EQ(ReadText(dir / "state.bin"), "bytes");
  EXPECT_FALSE(fs::exists(dir.string() + ".tmp"));
  CheckpointInfo info;
  std::string state;
  const std::unique_ptr<Model> back = LoadCheckpoint(dir.string(), &info, &state);
  EXPECT_EQ(info.stage, 2);
  EXPECT_EQ(info.batch, 9);
  EXPECT_EQ(info.config, "seed: 1\n");
  EXPECT_EQ(ReadCheckpointSeed(dir.string()), std::optional<uint32_t>(1));
  EXPECT_EQ(state, "bytes");
  EXPECT_EQ(AllParameters(*back), AllParameters(*model));
  ASSERT_TRUE(back->canonical_bounds().has_value());
  EXPECT_EQ(back->canonical_bounds()->max(), Eigen::Vector3d(0.5, 1, 2));
  // The model folder alone reads without optim (model/model_file.h).
  EXPECT_EQ(AllParameters(*LoadModel(dir.string())), AllParameters(*model));

  // Saving again replaces it; no .old or .tmp folder is left.
  SaveCheckpoint(dir.string(), *model, CheckpointInfo{3, 0, ""});
  LoadCheckpoint(dir.string(), &info, &state);
  EXPECT_EQ(info.stage, 3);
  EXPECT_EQ(state, "");
  EXPECT_FALSE(ReadCheckpointSeed(dir.string()).has_value());  // a config without a seed
  EXPECT_FALSE(fs::exists(dir.string() + ".old"));

  // The file names the stage's progress `batch` (format 3).
  std::string yaml = ReadText(dir / "checkpoint.yaml");
  EXPECT_NE(yaml.find("format: banmo-checkpoint-3\nstage: 3\nbatch: 0\n"), std::string::npos)
      << yaml;

  // An unknown checkpoint format names the file and what to do.
  yaml.replace(yaml.find("banmo-checkpoint-3"), 18, "banmo-checkpoint-5");
  std::ofstream(dir / "checkpoint.yaml") << yaml;
  try {
    LoadCheckpoint(dir.string(), &info);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find((dir / "checkpoint.yaml").string()), std::string::npos) << message;
    EXPECT_NE(message.find("banmo-checkpoint-5"), std::string::npos) << message;
    EXPECT_NE(message.find("solve again"), std::string::npos) << message;
  }
  fs::remove_all(dir);
}

// Format 2 (written before the batch index was named `batch`) holds the
// same number under `iteration`, and still resumes.
TEST(Checkpoint, FormatTwoReadsItsIterationKeyAsTheBatch) {
  const std::unique_ptr<Model> model = LoadModel(kV1);
  const fs::path dir = fs::path(::testing::TempDir()) / "banmo_checkpoint_format_2";
  fs::remove_all(dir);
  SaveCheckpoint(dir.string(), *model, CheckpointInfo{1, 4, "seed: 2\n"});
  std::ofstream(dir / "checkpoint.yaml")
      << "format: banmo-checkpoint-2\nstage: 2\niteration: 17\nconfig: |\n  seed: 2\n";
  CheckpointInfo info;
  LoadCheckpoint(dir.string(), &info);
  EXPECT_EQ(info.stage, 2);
  EXPECT_EQ(info.batch, 17);
  EXPECT_EQ(info.config, "seed: 2\n");

  // Format 3 without its `batch` key is a damaged file.
  std::ofstream(dir / "checkpoint.yaml")
      << "format: banmo-checkpoint-3\nstage: 2\niteration: 17\nconfig: |\n  seed: 2\n";
  try {
    LoadCheckpoint(dir.string(), &info);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("damaged"), std::string::npos) << e.what();
  }

  // A config whose seed is not a number: the seed read names the file.
  std::ofstream(dir / "checkpoint.yaml")
      << "format: banmo-checkpoint-3\nstage: 2\nbatch: 17\nconfig: |\n  seed: two\n";
  EXPECT_NO_THROW(LoadCheckpoint(dir.string(), &info));
  try {
    ReadCheckpointSeed(dir.string());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find((dir / "checkpoint.yaml").string()), std::string::npos) << message;
    EXPECT_NE(message.find("key 'seed' (line 1): expected an integer"), std::string::npos)
        << message;
  }
  fs::remove_all(dir);
}

// A flipped bit in params.bin or state.bin is an error naming the file
// (the checksums in model.yaml and checkpoint.yaml); files written before
// the checksums existed (no key) still load.
TEST(Checkpoint, FlippedBitsAreErrorsNamingTheFile) {
  const std::unique_ptr<Model> model = LoadModel(kV1);
  const fs::path dir = fs::path(::testing::TempDir()) / "banmo_checkpoint_checksums";
  fs::remove_all(dir);
  SaveCheckpoint(dir.string(), *model, CheckpointInfo{0, 1, "seed: 1\n"}, "solver bytes");
  EXPECT_NE(ReadText(dir / "model.yaml").find("params_checksum: fnv1a64:"), std::string::npos);
  EXPECT_NE(ReadText(dir / "checkpoint.yaml").find("state_checksum: fnv1a64:"), std::string::npos);
  auto load_error = [&] {
    try {
      CheckpointInfo info;
      std::string state;
      LoadCheckpoint(dir.string(), &info, &state);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  ASSERT_EQ(load_error(), "");
  auto flip = [](const fs::path& path, std::size_t at) {
    std::string bytes = ReadText(path);
    bytes[at] = static_cast<char>(bytes[at] ^ 0x10);
    std::ofstream(path, std::ios::binary) << bytes;
  };
  const std::string params = ReadText(dir / "params.bin");
  flip(dir / "params.bin", params.size() - 3);  // inside a parameter value
  std::string error = load_error();
  EXPECT_NE(error.find((dir / "params.bin").string() + ": checksum fnv1a64:"), std::string::npos)
      << error;
  EXPECT_NE(error.find("recorded in " + (dir / "model.yaml").string()), std::string::npos) << error;
  std::ofstream(dir / "params.bin", std::ios::binary) << params;
  flip(dir / "state.bin", 3);
  error = load_error();
  EXPECT_NE(error.find((dir / "state.bin").string() + ": checksum"), std::string::npos) << error;
  // Without the keys (files of an older banmo): accepted, as before.
  auto drop_line = [](const fs::path& path, const std::string& key) {
    std::string text = ReadText(path);
    const std::size_t at = text.find(key);
    text.erase(at, text.find('\n', at) + 1 - at);
    std::ofstream(path, std::ios::binary) << text;
  };
  drop_line(dir / "checkpoint.yaml", "state_checksum: ");
  drop_line(dir / "model.yaml", "params_checksum: ");
  EXPECT_EQ(load_error(), "");
}

}  // namespace
}  // namespace banmo
