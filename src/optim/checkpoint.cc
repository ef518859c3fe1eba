#include "banmo/optim/checkpoint.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "banmo/model/model_file.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/checksum.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"
#include "banmo/util/logging.h"
#include "banmo/util/yaml.h"

namespace banmo {
namespace {

// Format 3 names a stage's progress `batch`; format 2 (key `iteration`,
// the same number) still loads.
constexpr char kCheckpointFormat[] = "banmo-checkpoint-3";
constexpr char kCheckpointFormatV2[] = "banmo-checkpoint-2";

// What to do when checkpoint.yaml cannot be read.
constexpr char kDamaged[] = ": the file is damaged; solve again (without --resume)";

std::string ReadFile(const std::string& path) { return ReadRegularFile(path); }

// Stage, batch and config of checkpoint.yaml, or of model.yaml in a
// checkpoint written before the model file existed.
CheckpointInfo ReadInfo(const std::string& dir) {
  std::string path = dir + "/checkpoint.yaml";
  std::string expected_format = kCheckpointFormat;
  if (!PathExists(path)) {
    path = dir + "/model.yaml";
    expected_format = kLegacyCheckpointFormat;
  }
  CheckpointInfo info;
  const YamlNode root = YamlNode::Load(path, kDamaged);
  const std::string format = root.Required("format").As<std::string>();
  const bool known = format == expected_format ||
                     (expected_format == kCheckpointFormat && format == kCheckpointFormatV2);
  if (!known) {
    ThrowInputError(path, ": unknown checkpoint format '", format, "' (expected ", expected_format,
                    "); resume with the banmo that wrote it, or solve again with this one");
  }
  root.ReadRequired("stage", &info.stage);
  // Formats before 3 count the stage's batches under `iteration`.
  root.ReadRequired(format == kCheckpointFormat ? "batch" : "iteration", &info.batch);
  root.ReadRequired("config", &info.config);
  return info;
}

// checkpoint.yaml's state_checksum ("" if absent or a legacy checkpoint).
std::string ReadStateChecksum(const std::string& dir) {
  const std::string path = dir + "/checkpoint.yaml";
  if (!PathExists(path)) return "";
  std::string checksum;
  YamlNode::Load(path, kDamaged).ReadIfPresent("state_checksum", &checksum);
  return checksum;
}

}  // namespace

void SaveCheckpoint(const std::string& final_dir, const Model& model, const CheckpointInfo& info,
                    const std::string& solver_state) {
  // The files go to a fresh folder beside the target, which then replaces
  // the old checkpoint by two renames (old -> .old, new -> target): at every
  // moment one complete checkpoint exists on disk (LoadCheckpoint falls back
  // to .old if a crash hit between the renames).
  namespace fs = std::filesystem;
  const std::string dir = final_dir + ".tmp";
  std::error_code ec;
  fs::remove_all(dir, ec);
  MakeDirectories(dir);
  // A failed write (full disk) leaves no checkpoint.tmp behind.
  try {
    WriteModelFiles(dir, model);

    YAML::Emitter out;
    out << YAML::BeginMap;
    out << YAML::Key << "format" << YAML::Value << kCheckpointFormat;
    out << YAML::Key << "stage" << YAML::Value << info.stage;
    out << YAML::Key << "batch" << YAML::Value << info.batch;
    if (!solver_state.empty()) {
      out << YAML::Key << "state_checksum" << YAML::Value << ContentChecksum(solver_state);
    }
    out << YAML::Key << "config" << YAML::Value << YAML::Literal << info.config;
    out << YAML::EndMap;
    CHECK(out.good()) << "YAML emitter: " << out.GetLastError();
    WriteFileAtomic(dir + "/checkpoint.yaml", std::string(out.c_str()) + "\n");
    if (!solver_state.empty()) WriteFileAtomic(dir + "/state.bin", solver_state);
  } catch (...) {
    fs::remove_all(dir, ec);
    throw;
  }

  const std::string old = final_dir + ".old";
  fs::remove_all(old, ec);
  if (fs::exists(final_dir)) {
    fs::rename(final_dir, old, ec);
    if (ec)
      ThrowInputError(final_dir, ": cannot move the previous checkpoint aside: ", ec.message());
  }
  fs::rename(dir, final_dir, ec);
  if (ec) ThrowInputError(final_dir, ": cannot move the new checkpoint into place: ", ec.message());
  fs::remove_all(old, ec);
}

std::optional<uint32_t> ReadCheckpointSeed(const std::string& dir) {
  const std::string folder = ResolveModelFolder(dir);
  const CheckpointInfo info = ReadInfo(folder);
  const YamlNode config =
      YamlNode::Parse(info.config, folder + "/checkpoint.yaml (config)", kDamaged);
  uint32_t seed = 0;
  if (config.ReadIfPresent("seed", &seed)) return seed;
  return std::nullopt;
}

std::unique_ptr<Model> LoadCheckpoint(const std::string& requested_dir, CheckpointInfo* info,
                                      std::string* solver_state) {
  const std::string dir = ResolveModelFolder(requested_dir);
  std::unique_ptr<Model> model = ReadModelFiles(dir);
  if (info != nullptr) *info = ReadInfo(dir);
  if (solver_state != nullptr) {
    const std::string state_path = dir + "/state.bin";
    *solver_state = PathExists(state_path) ? ReadFile(state_path) : std::string();
    // Checkpoints written before the checksum existed have none (accepted).
    const std::string checksum = ReadStateChecksum(dir);
    if (!solver_state->empty() && !checksum.empty()) {
      VerifyChecksum(state_path, *solver_state, checksum, dir + "/checkpoint.yaml",
                     "state_checksum");
    }
  }
  return model;
}

}  // namespace banmo
