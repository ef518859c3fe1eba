#include "banmo/model/model_file.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <vector>

#include "banmo/geometry/box.h"
#include "banmo/model/model_options_fields.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/checksum.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"
#include "banmo/util/input_file.h"
#include "banmo/util/logging.h"
#include "banmo/util/yaml.h"

namespace banmo {
namespace {

// params.bin: "BANMOPB1", uint64 count, count little-endian doubles in
// Model::ForEachBlock order.
constexpr char kMagic[8] = {'B', 'A', 'N', 'M', 'O', 'P', 'B', '1'};

// What to do when a model folder cannot be read.
constexpr char kWhatToDo[] =
    "; pass the folder written by banmo solve (OUT/checkpoint), or solve again to write it";

std::string ReadFile(const std::string& path) {
  return ReadRegularFile(path, kMaxInputFileBytes, kWhatToDo);
}

// What an unknown key of model.yaml means.
constexpr char kUnknownKeyNote[] = " (the file is damaged or from another banmo)";

// ---- model.yaml. ----

// The ray sampling of the last stage of a legacy checkpoint's solver config
// text: `defaults:` overridden by the last entry of `stages:`; keys absent
// from both keep TrainingSampling's defaults (the solver's stage defaults).
// Not recorded when the text has no stages.
std::optional<TrainingSampling> LegacyTrainingSampling(const YamlNode& config) {
  const YamlNode stages = config["stages"];
  if (stages.size() == 0) return std::nullopt;
  TrainingSampling s;
  for (const YamlNode& stage : {config["defaults"], stages[stages.size() - 1]}) {
    if (!stage.IsMap()) continue;
    stage.ReadIfPresent("samples_per_ray", &s.samples_per_ray);
    const YamlNode sampling = stage["sampling"];
    sampling.ReadIfPresent("near_far_margin", &s.near_far_margin);
    sampling.ReadIfPresent("importance_depth", &s.importance_depth);
    sampling.ReadIfPresent("clip_to_box", &s.clip_to_box);
    sampling.ReadIfPresent("clip_margin", &s.clip_margin);
    sampling.ReadIfPresent("importance_samples", &s.importance_samples);
    sampling.ReadIfPresent("min_sdf_sample", &s.min_sdf_sample);
  }
  return s;
}

}  // namespace

void WriteModelFiles(const std::string& dir, const Model& model) {
  // Parameters first, then the YAML that describes them; the reader checks
  // that the sizes agree.
  std::string params(kMagic, sizeof(kMagic));
  uint64_t count = 0;
  std::string values;
  model.ForEachBlock([&](const std::string&, const double* data, int size) {
    values.append(reinterpret_cast<const char*>(data), sizeof(double) * size);
    count += size;
  });
  params.append(reinterpret_cast<const char*>(&count), sizeof(count));
  params += values;
  WriteFileAtomic(dir + "/params.bin", params);
  const std::string params_checksum = ContentChecksum(params);

  YAML::Emitter out;
  YamlWriter<> writer(&out);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kModelFileFormat;
  out << YAML::Key << "parameters" << YAML::Value << count;
  out << YAML::Key << "params_checksum" << YAML::Value << params_checksum;
  out << YAML::Key << "scene_scale" << YAML::Value << FormatDouble(model.scene_scale());
  writer("canonical_origin", model.canonical_origin());
  writer("options", model.options());
  if (model.canonical_bounds()) {
    out << YAML::Key << "canonical_bounds" << YAML::Value << YAML::BeginMap;
    writer("min", model.canonical_bounds()->min());
    writer("max", model.canonical_bounds()->max());
    out << YAML::EndMap;
  }
  if (model.training_sampling()) {
    const TrainingSampling& s = *model.training_sampling();
    out << YAML::Key << "training_sampling" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "samples_per_ray" << YAML::Value << s.samples_per_ray;
    out << YAML::Key << "near_far_margin" << YAML::Value << FormatDouble(s.near_far_margin);
    out << YAML::Key << "importance_depth" << YAML::Value
        << (s.importance_depth ? "true" : "false");
    if (s.clip_to_box) {  // absent in files of models trained without it
      out << YAML::Key << "clip_to_box" << YAML::Value << "true";
      out << YAML::Key << "clip_margin" << YAML::Value << FormatDouble(s.clip_margin);
    }
    if (s.importance_samples > 0) {  // absent in files of models trained without it
      out << YAML::Key << "importance_samples" << YAML::Value << s.importance_samples;
    }
    if (s.min_sdf_sample) {  // absent in files of models trained without it
      out << YAML::Key << "min_sdf_sample" << YAML::Value << "true";
    }
    out << YAML::EndMap;
  }
  out << YAML::Key << "root_correction" << YAML::Value << kRootCorrectionObjectSide;
  out << YAML::Key << "videos" << YAML::Value << YAML::BeginSeq;
  for (int v = 0; v < model.num_videos(); ++v) {
    const VideoParameters& vp = model.video(v);
    out << YAML::BeginMap;
    out << YAML::Key << "frames" << YAML::Value << static_cast<int>(vp.frames.size());
    out << YAML::Key << "width" << YAML::Value << vp.camera.width;
    out << YAML::Key << "height" << YAML::Value << vp.camera.height;
    out << YAML::Key << "intrinsics" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (int k = 0; k < 4; ++k) out << FormatDouble(vp.camera.intrinsics[k]);
    out << YAML::EndSeq << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::EndMap;
  CHECK(out.good()) << "YAML emitter: " << out.GetLastError();
  WriteFileAtomic(dir + "/model.yaml", std::string(out.c_str()) + "\n");
}

std::string ResolveModelFolder(const std::string& dir) {
  if (!PathExists(dir + "/model.yaml") && PathExists(dir + ".old/model.yaml")) {
    return dir + ".old";  // a save was interrupted between its two renames
  }
  return dir;
}

namespace {

// Re-expresses camera-side corrections (G = dG_cam G0) on the object side
// (G = G0 dG): dG = G0^-1 dG_cam G0, the same G up to rounding.
void ObjectSideRootCorrections(Model* model) {
  for (int v = 0; v < model->num_videos(); ++v) {
    for (FrameParameters& f : model->video(v).frames) {
      Pose init_inverse, tmp;
      PoseInverse(f.root_init.data(), init_inverse.data());
      PoseCompose(f.root_delta.data(), f.root_init.data(), tmp.data());
      PoseCompose(init_inverse.data(), tmp.data(), f.root_delta.data());
    }
  }
}

// model.yaml of folder `dir` parsed, with its format checked (sets *legacy for
// the solver's older checkpoint format).
YamlNode LoadModelYaml(const std::string& dir, const std::string& yaml_path, bool* legacy) {
  if (!PathExists(yaml_path)) {
    ThrowInputError(dir, ": not a model folder (no model.yaml)", kWhatToDo);
  }
  const YamlNode root = YamlNode::Load(yaml_path, kWhatToDo);
  if (!root.IsMap()) {
    ThrowInputError(yaml_path,
                    ": expected a map of keys (format, parameters, ...): the file is "
                    "damaged",
                    kWhatToDo);
  }
  std::string format;
  root.ReadRequired("format", &format);
  *legacy = format == kLegacyCheckpointFormat;
  if (!*legacy && format != kModelFileFormat) {
    ThrowInputError(yaml_path, ": unknown model format '", format, "' (this banmo reads ",
                    kModelFileFormat, " and ", kLegacyCheckpointFormat,
                    "); read it with the banmo that wrote it, or solve again with this one");
  }
  if (!*legacy) {
    root.CheckKeys(
        {"format", "parameters", "params_checksum", "scene_scale", "canonical_origin", "options",
         "canonical_bounds", "training_sampling", "root_correction", "videos"},
        kUnknownKeyNote);
    if (root["training_sampling"].IsMap()) {
      root["training_sampling"].CheckKeys(
          {"samples_per_ray", "near_far_margin", "importance_depth", "clip_to_box", "clip_margin",
           "importance_samples", "min_sdf_sample"},
          kUnknownKeyNote);
    }
    if (root["canonical_bounds"].IsMap()) {
      root["canonical_bounds"].CheckKeys({"min", "max"}, kUnknownKeyNote);
    }
    for (std::size_t v = 0; v < root["videos"].size(); ++v) {
      const YamlNode video = root["videos"][v];
      if (video.IsMap())
        video.CheckKeys({"frames", "width", "height", "intrinsics"}, kUnknownKeyNote);
    }
  }
  return root;
}

// The model options and training sampling of a legacy checkpoint: the
// config's model section, the sizes those of model_size (absent before
// automatic sizing existed).
void ReadLegacyOptions(const YamlNode& root, ModelOptions* options,
                       std::optional<TrainingSampling>* sampling) {
  std::string config_text;
  root.ReadRequired("config", &config_text);
  const YamlNode config = YamlNode::Parse(config_text, root.source() + " (config)", kWhatToDo);
  config.ReadIfPresent("model", options);
  const YamlNode size = root["model_size"];
  if (size.IsDefined()) {
    size.ReadRequired("num_bones", &options->num_bones);
    size.ReadRequired("sdf_width", &options->field.sdf_width);
    size.ReadRequired("color_width", &options->field.color_width);
  }
  *sampling = LegacyTrainingSampling(config);
}

// The model options (key 'options') and the optional training_sampling.
void ReadOptions(const YamlNode& root, ModelOptions* options,
                 std::optional<TrainingSampling>* sampling) {
  root.ReadRequired("options", options);
  const YamlNode s = root["training_sampling"];
  if (s.IsDefined()) {
    TrainingSampling t;
    s.ReadRequired("samples_per_ray", &t.samples_per_ray);
    s.ReadRequired("near_far_margin", &t.near_far_margin);
    s.ReadRequired("importance_depth", &t.importance_depth);
    if (s.Has("clip_to_box")) {
      s.ReadRequired("clip_to_box", &t.clip_to_box);
      s.ReadRequired("clip_margin", &t.clip_margin);
    }
    s.ReadIfPresent("importance_samples", &t.importance_samples);
    s.ReadIfPresent("min_sdf_sample", &t.min_sdf_sample);
    // 1024: the stage configuration's limit (docs/robustness.md).
    if (t.samples_per_ray <= 0 || t.samples_per_ray > 1024 || !(t.near_far_margin >= 0) ||
        !(t.clip_margin >= 0) || t.importance_samples < 0 || t.importance_samples > 1024) {
      s.Fail(
          "expected samples_per_ray in [1, 1024], near_far_margin >= 0, clip_margin >= 0 and "
          "importance_samples in [0, 1024]");
    }
    *sampling = t;
  }
}

// Frame counts and cameras of the videos (key 'videos').
void ReadVideos(const YamlNode& root, std::vector<int>* frames,
                std::vector<PinholeCamera>* cameras) {
  const YamlNode videos = root["videos"];
  if (!videos.IsSequence()) videos.TypeError("a list of videos");
  for (size_t v = 0; v < videos.size(); ++v) {
    const YamlNode video = videos[v];
    int count = 0;
    PinholeCamera cam;
    video.ReadRequired("frames", &count);
    video.ReadRequired("width", &cam.width);
    video.ReadRequired("height", &cam.height);
    std::vector<double> k;
    video.ReadRequired("intrinsics", &k);
    // The dataset format's limits (docs/robustness.md): 100000 frames per
    // video, sides of at most 16384 px.
    if (count < 0 || count > 100000 || cam.width <= 0 || cam.height <= 0 || cam.width > 16384 ||
        cam.height > 16384 || k.size() != 4) {
      video.Fail("expected frames in [0, 100000], width and height in [1, 16384] and 4 intrinsics");
    }
    for (int i = 0; i < 4; ++i) cam.intrinsics[i] = k[i];
    frames->push_back(count);
    cameras->push_back(cam);
  }
}

// params.bin of `dir` into the model's blocks, after checking its magic and
// that its value count is `expected_count` (model.yaml's) and the model's.
void ReadParameters(const std::string& dir, const std::string& yaml_path, uint64_t expected_count,
                    const std::string& checksum, Model* model) {
  const std::string params_path = dir + "/params.bin";
  const std::string params = ReadFile(params_path);
  uint64_t count = 0;
  if (params.size() < sizeof(kMagic) + sizeof(count) ||
      std::memcmp(params.data(), kMagic, sizeof(kMagic)) != 0) {
    ThrowInputError(params_path, ": not a banmo parameter file (the file is damaged)", kWhatToDo);
  }
  std::memcpy(&count, params.data() + sizeof(kMagic), sizeof(count));
  uint64_t model_count = 0;
  model->ForEachBlock([&](const std::string&, const double*, int size) { model_count += size; });
  if (count != expected_count || count != model_count ||
      params.size() != sizeof(kMagic) + sizeof(count) + sizeof(double) * count) {
    ThrowInputError(params_path, ": holds ", count, " values (", params.size(),
                    " bytes), expected ", model_count, " for the model in ", yaml_path,
                    " (the files are damaged or from different saves)", kWhatToDo);
  }
  // After the structural checks (their messages say more). Files written before the checksum
  // existed have none (and are accepted).
  if (!checksum.empty()) {
    try {
      VerifyChecksum(params_path, params, checksum, yaml_path, "params_checksum");
    } catch (const InputError& e) {
      ThrowInputError(e.what(), kWhatToDo);
    }
  }
  const char* p = params.data() + sizeof(kMagic) + sizeof(count);
  model->ForEachBlock([&](const std::string&, double* data, int size) {
    std::memcpy(data, p, sizeof(double) * size);
    p += sizeof(double) * size;
  });
}

std::unique_ptr<Model> ReadModelFilesUnguarded(const std::string& dir) {
  const std::string yaml_path = dir + "/model.yaml";
  bool legacy = false;
  const YamlNode root = LoadModelYaml(dir, yaml_path, &legacy);
  ModelOptions options;
  std::optional<TrainingSampling> sampling;
  if (legacy) {
    ReadLegacyOptions(root, &options, &sampling);
  } else {
    ReadOptions(root, &options, &sampling);
  }
  try {
    options.Check();
  } catch (const InputError& e) {
    ThrowInputError(yaml_path, ": ", e.what(), kWhatToDo);
  }

  double scene_scale = 1.0;  // legacy checkpoints written before the key existed
  if (legacy) {
    root.ReadIfPresent("scene_scale", &scene_scale);
  } else {
    root.ReadRequired("scene_scale", &scene_scale);
  }
  if (!(scene_scale > 0))
    root["scene_scale"].Fail("expected a finite number > 0, got ", scene_scale);
  uint64_t expected_count = 0;
  root.ReadRequired("parameters", &expected_count);
  std::string params_checksum;
  if (!legacy) root.ReadIfPresent("params_checksum", &params_checksum);
  std::string root_correction = "camera";  // files written before the key existed
  root.ReadIfPresent("root_correction", &root_correction);
  if (root_correction != kRootCorrectionObjectSide && root_correction != "camera") {
    root["root_correction"].Fail("expected '", kRootCorrectionObjectSide, "' or 'camera', got '",
                                 root_correction, "'");
  }

  std::vector<int> frames;
  std::vector<PinholeCamera> cameras;
  ReadVideos(root, &frames, &cameras);
  auto model = std::make_unique<Model>(options, frames, cameras);
  model->set_scene_scale(scene_scale);
  if (sampling) model->set_training_sampling(*sampling);
  if (!legacy && root.Has("canonical_origin")) {  // zero in files written before it
    model->set_canonical_origin(root["canonical_origin"].As<Eigen::Vector3d>());
  }
  const YamlNode bounds = root["canonical_bounds"];
  if (!legacy && bounds.IsDefined()) {
    const Eigen::AlignedBox3d box(bounds.Required("min").As<Eigen::Vector3d>(),
                                  bounds.Required("max").As<Eigen::Vector3d>());
    if (!IsValidBox(box)) bounds.Fail("expected finite corners with max > min on every axis");
    model->set_canonical_bounds(box);
  }
  ReadParameters(dir, yaml_path, expected_count, params_checksum, model.get());
  if (root_correction != kRootCorrectionObjectSide) ObjectSideRootCorrections(model.get());
  return model;
}

}  // namespace

std::unique_ptr<Model> ReadModelFiles(const std::string& dir) {
  try {
    return ReadModelFilesUnguarded(dir);
  } catch (const YAML::Exception& e) {  // a shape the checks above did not foresee
    ThrowInputError(dir, "/model.yaml: malformed (", e.what(), "): the file is damaged", kWhatToDo);
  }
}

std::unique_ptr<Model> LoadModel(const std::string& dir) {
  return ReadModelFiles(ResolveModelFolder(dir));
}

}  // namespace banmo
