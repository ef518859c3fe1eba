#include "banmo/optim/checkpoint.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"

namespace banmo {
namespace {

// params.bin: "BANMOPB1", uint64 count, count little-endian doubles in
// Model::ForEachBlock order.
constexpr char kMagic[8] = {'B', 'A', 'N', 'M', 'O', 'P', 'B', '1'};

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInputError(path, ": cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
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
  // Parameters first, then the YAML that describes them, then the state; a
  // reader checks that the sizes agree.
  std::string params(kMagic, sizeof(kMagic));
  uint64_t count = 0;
  std::string values;
  const_cast<Model&>(model).ForEachBlock([&](const std::string&, double* data, int size) {
    values.append(reinterpret_cast<const char*>(data), sizeof(double) * size);
    count += size;
  });
  params.append(reinterpret_cast<const char*>(&count), sizeof(count));
  params += values;
  WriteFileAtomic(dir + "/params.bin", params);

  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "banmo-checkpoint-1";
  out << YAML::Key << "stage" << YAML::Value << info.stage;
  out << YAML::Key << "iteration" << YAML::Value << info.iteration;
  out << YAML::Key << "parameters" << YAML::Value << count;
  out << YAML::Key << "scene_scale" << YAML::Value << FormatDouble(model.scene_scale());
  // The model's current sizes: automatic sizing (optim/auto_size.h) may have
  // grown them beyond the config's model section.
  out << YAML::Key << "model_size" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "num_bones" << YAML::Value << model.num_bones();
  out << YAML::Key << "sdf_width" << YAML::Value << model.options().field.sdf_width;
  out << YAML::Key << "color_width" << YAML::Value << model.options().field.color_width;
  out << YAML::EndMap;
  out << YAML::Key << "videos" << YAML::Value << YAML::BeginSeq;
  for (int v = 0; v < model.num_videos(); ++v) {
    const VideoParameters& vp = model.video(v);
    out << YAML::BeginMap;
    out << YAML::Key << "frames" << YAML::Value << static_cast<int>(vp.frames.size());
    out << YAML::Key << "width" << YAML::Value << vp.camera.width;
    out << YAML::Key << "height" << YAML::Value << vp.camera.height;
    out << YAML::Key << "intrinsics" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (int k = 0; k < 4; ++k) out << vp.camera.intrinsics[k];
    out << YAML::EndSeq << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "config" << YAML::Value << YAML::Literal << info.config;
  out << YAML::EndMap;
  WriteFileAtomic(dir + "/model.yaml", std::string(out.c_str()) + "\n");
  if (!solver_state.empty()) WriteFileAtomic(dir + "/state.bin", solver_state);

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

std::unique_ptr<Model> LoadCheckpoint(const std::string& requested_dir, CheckpointInfo* info,
                                      std::string* solver_state) {
  std::string dir = requested_dir;
  if (!std::filesystem::exists(dir + "/model.yaml") &&
      std::filesystem::exists(dir + ".old/model.yaml")) {
    dir += ".old";  // a save was interrupted between its two renames
  }
  const std::string yaml_path = dir + "/model.yaml";
  if (!std::filesystem::exists(yaml_path)) {
    ThrowInputError(dir, ": not a checkpoint folder (no model.yaml)");
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(yaml_path);
  } catch (const YAML::Exception& e) {
    ThrowInputError(yaml_path, ": ", e.what());
  }
  CheckpointInfo local;
  CheckpointInfo& ci = info != nullptr ? *info : local;
  std::vector<int> frames;
  std::vector<PinholeCamera> cameras;
  uint64_t expected = 0;
  double scene_scale = 1.0;  // checkpoints written before the key existed
  YAML::Node model_size;
  try {
    if (root["format"].as<std::string>() != "banmo-checkpoint-1") {
      ThrowInputError(yaml_path, ": unknown checkpoint format '", root["format"].as<std::string>(),
                      "'");
    }
    ci.stage = root["stage"].as<int>();
    ci.iteration = root["iteration"].as<int>();
    ci.config = root["config"].as<std::string>();
    expected = root["parameters"].as<uint64_t>();
    if (root["scene_scale"]) scene_scale = root["scene_scale"].as<double>();
    model_size = root["model_size"];  // absent in checkpoints written before auto-sizing
    for (const YAML::Node& v : root["videos"]) {
      frames.push_back(v["frames"].as<int>());
      PinholeCamera cam;
      cam.width = v["width"].as<int>();
      cam.height = v["height"].as<int>();
      for (int k = 0; k < 4; ++k) cam.intrinsics[k] = v["intrinsics"][k].as<double>();
      cameras.push_back(cam);
    }
  } catch (const YAML::Exception& e) {
    ThrowInputError(yaml_path, ": missing or malformed key: ", e.what());
  }
  if (!(scene_scale > 0 && std::isfinite(scene_scale))) {
    ThrowInputError(yaml_path, ": key 'scene_scale': expected a finite number > 0, got ",
                    scene_scale);
  }
  SolverConfig config = ParseSolverConfig(ci.config, yaml_path + " (config)");
  if (model_size) {
    try {
      config.model.num_bones = model_size["num_bones"].as<int>();
      config.model.field.sdf_width = model_size["sdf_width"].as<int>();
      config.model.field.color_width = model_size["color_width"].as<int>();
    } catch (const YAML::Exception& e) {
      ThrowInputError(yaml_path, ": malformed key 'model_size': ", e.what());
    }
    try {
      config.model.Check();
    } catch (const InputError& e) {
      ThrowInputError(yaml_path, ": model_size: ", e.what());
    }
  }
  auto model = std::make_unique<Model>(config.model, frames, cameras);
  model->set_scene_scale(scene_scale);

  const std::string params_path = dir + "/params.bin";
  const std::string params = ReadFile(params_path);
  uint64_t count = 0;
  if (params.size() < sizeof(kMagic) + sizeof(count) ||
      std::memcmp(params.data(), kMagic, sizeof(kMagic)) != 0) {
    ThrowInputError(params_path, ": not a banmo parameter file");
  }
  std::memcpy(&count, params.data() + sizeof(kMagic), sizeof(count));
  uint64_t model_count = 0;
  model->ForEachBlock([&](const std::string&, double*, int size) { model_count += size; });
  if (count != expected || count != model_count ||
      params.size() != sizeof(kMagic) + sizeof(count) + sizeof(double) * count) {
    ThrowInputError(params_path, ": holds ", count, " values (", params.size(),
                    " bytes), expected ", model_count, " for the model in ", yaml_path);
  }
  const char* p = params.data() + sizeof(kMagic) + sizeof(count);
  model->ForEachBlock([&](const std::string&, double* data, int size) {
    std::memcpy(data, p, sizeof(double) * size);
    p += sizeof(double) * size;
  });
  if (solver_state != nullptr) {
    const std::string state_path = dir + "/state.bin";
    *solver_state = std::filesystem::exists(state_path) ? ReadFile(state_path) : std::string();
  }
  return model;
}

}  // namespace banmo
