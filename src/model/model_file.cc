#include "banmo/model/model_file.h"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <locale>
#include <optional>
#include <set>
#include <sstream>
#include <vector>

#include "banmo/geometry/box.h"
#include "banmo/model/model_options_fields.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/checksum.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"
#include "banmo/util/input_file.h"
#include "banmo/util/logging.h"

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

// ---- ModelOptions as YAML (the field lists of model_options_fields.h). ----

class OptionsWriter {
 public:
  explicit OptionsWriter(YAML::Emitter* out) : out_(*out) {}

  template <class T>
  void operator()(const char* key, T& value) {
    out_ << YAML::Key << key << YAML::Value;
    Write(value);
  }

  template <class S>
  void WriteStruct(S& value) {
    out_ << YAML::BeginMap;
    VisitFields(*this, value);
    out_ << YAML::EndMap;
  }

 private:
  void Write(int v) { out_ << v; }
  void Write(uint32_t v) { out_ << v; }
  void Write(double v) { out_ << FormatDouble(v); }
  void Write(bool v) { out_ << (v ? "true" : "false"); }
  void Write(Activation v) { out_ << (v == Activation::kRelu ? "relu" : "softplus"); }
  void Write(DensityModel v) { out_ << EnumName(v); }
  void Write(std::optional<double>& v) {
    if (v) {
      Write(*v);
    } else {
      out_ << "auto";
    }
  }
  void Write(std::vector<double>& v) {
    out_ << YAML::Flow << YAML::BeginSeq;
    for (double x : v) Write(x);
    out_ << YAML::EndSeq;
  }
  template <class S>
  void Write(S& v) {
    WriteStruct(v);
  }

  YAML::Emitter& out_;
};

// Reads the keys present in a map into a struct (absent keys keep their
// values); an unknown key or a value of the wrong type is an InputError
// naming `source` and the key path.
class OptionsReader {
 public:
  OptionsReader(const std::string& source, std::string path, YAML::Node node)
      : source_(source), path_(std::move(path)), node_(std::move(node)) {}

  // Reads the node into *value (a struct, number, flag, list...).
  template <class T>
  void ReadInto(T* value) {
    Read(value);
  }

  template <class S>
  void ReadStruct(S* value) {
    if (node_.IsNull()) return;
    if (!node_.IsMap()) Fail(node_, "a map");
    std::set<std::string> known;
    KeyNames names{&known};
    VisitFields(names, *value);
    for (auto it = node_.begin(); it != node_.end(); ++it) {
      const std::string name = it->first.IsScalar() ? it->first.Scalar() : std::string("?");
      if (!known.count(name)) {
        ThrowInputError(source_, ": unknown key '", Join(name), "'", kWhatToDo);
      }
    }
    VisitFields(*this, *value);
  }

  template <class T>
  void operator()(const char* key, T& value) {
    const YAML::Node child = node_[key];
    if (!child.IsDefined()) return;
    OptionsReader reader(source_, Join(key), child);
    reader.Read(&value);
  }

 private:
  struct KeyNames {
    std::set<std::string>* keys;
    template <class T>
    void operator()(const char* key, T&) {
      keys->insert(key);
    }
  };

  std::string Join(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& expected) const {
    ThrowInputError(source_, ": key '", path_, "': expected ", expected, ", got ",
                    node.IsScalar() ? "'" + node.Scalar() + "'" : std::string("a non-scalar"),
                    kWhatToDo);
  }

  // A finite number (classic locale), or false.
  static bool Number(const YAML::Node& node, double* value) {
    if (!node.IsScalar()) return false;
    std::istringstream in(node.Scalar());
    in.imbue(std::locale::classic());
    double v = 0.0;
    in >> v;
    if (in.fail() || !(in >> std::ws).eof() || !std::isfinite(v)) return false;
    *value = v;
    return true;
  }
  // Optional sign and decimal digits, in [lo, hi].
  long long Integer(long long lo, long long hi) const {
    const std::string s = node_.IsScalar() ? node_.Scalar() : std::string();
    const std::string expected = "an integer in " + std::to_string(lo) + ".." + std::to_string(hi);
    const size_t first = (!s.empty() && (s[0] == '+' || s[0] == '-')) ? 1 : 0;
    if (first == s.size()) Fail(node_, expected);
    for (size_t i = first; i < s.size(); ++i) {
      if (s[i] < '0' || s[i] > '9') Fail(node_, expected);
    }
    errno = 0;
    const long long v = std::strtoll(s.c_str(), nullptr, 10);
    if (errno == ERANGE || v < lo || v > hi) Fail(node_, expected);
    return v;
  }

  void Read(int* v) {
    *v =
        static_cast<int>(Integer(std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
  }
  void Read(uint32_t* v) {
    *v = static_cast<uint32_t>(Integer(0, std::numeric_limits<uint32_t>::max()));
  }
  void Read(uint64_t* v) {
    *v = static_cast<uint64_t>(Integer(0, std::numeric_limits<long long>::max()));
  }
  void Read(double* v) {
    if (!Number(node_, v)) Fail(node_, "a finite number");
  }
  void Read(bool* v) {
    const std::string s = node_.IsScalar() ? node_.Scalar() : std::string();
    if (s == "true" || s == "True" || s == "TRUE") {
      *v = true;
    } else if (s == "false" || s == "False" || s == "FALSE") {
      *v = false;
    } else {
      Fail(node_, "true or false");
    }
  }
  void Read(std::string* v) {
    if (!node_.IsScalar()) Fail(node_, "a string");
    *v = node_.Scalar();
  }
  void Read(Activation* v) {
    const std::string s = node_.IsScalar() ? node_.Scalar() : std::string();
    if (s == "softplus") {
      *v = Activation::kSoftplus;
    } else if (s == "relu") {
      *v = Activation::kRelu;
    } else {
      Fail(node_, "softplus or relu");
    }
  }
  // Absent in files written before the option: those models are VolSDF's
  // (the struct's default).
  void Read(DensityModel* v) {
    const std::optional<DensityModel> d =
        ParseEnum<DensityModel>(node_.IsScalar() ? node_.Scalar() : std::string());
    if (!d) Fail(node_, "one of " + EnumChoices<DensityModel>());
    *v = *d;
  }
  void Read(std::optional<double>* v) {
    if (node_.IsScalar() && node_.Scalar() == "auto") {
      v->reset();
      return;
    }
    double x = 0.0;
    if (!Number(node_, &x)) Fail(node_, "auto or a finite number");
    *v = x;
  }
  void Read(std::vector<double>* v) {
    if (node_.IsNull()) {
      v->clear();
      return;
    }
    if (!node_.IsSequence()) Fail(node_, "a list of numbers");
    v->assign(node_.size(), 0.0);
    for (size_t i = 0; i < node_.size(); ++i) {
      OptionsReader item(source_, path_ + "[" + std::to_string(i) + "]", node_[i]);
      item.Read(&(*v)[i]);
    }
  }
  template <class S>
  void Read(S* v) {
    ReadStruct(v);
  }

  const std::string& source_;
  std::string path_;
  YAML::Node node_;
};

// ---- model.yaml. ----

// Type tests that are false (instead of throwing) for a missing key's node.
bool IsMap(const YAML::Node& node) { return node.IsDefined() && node.IsMap(); }
bool IsSequence(const YAML::Node& node) { return node.IsDefined() && node.IsSequence(); }

// An unknown or repeated key of `map` (written by a newer banmo, or a typo)
// is an error naming the file and the key: it would otherwise be ignored.
void CheckKnownKeys(const std::string& source, const std::string& path, const YAML::Node& map,
                    const std::set<std::string>& known) {
  std::set<std::string> seen;
  for (const auto& kv : map) {
    const std::string key = kv.first.Scalar();
    if (!known.count(key)) {
      ThrowInputError(source, ": unknown key '", path, key,
                      "' (the file is damaged or from "
                      "another banmo)",
                      kWhatToDo);
    }
    if (!seen.insert(key).second) {
      ThrowInputError(source, ": duplicate key '", path, key, "' (the file is damaged)", kWhatToDo);
    }
  }
}

// Reads node[key] into *value when the key is present (path names it).
template <class T>
void ReadOptional(const std::string& source, const std::string& path, const YAML::Node& node,
                  const char* key, T* value) {
  if (!IsMap(node)) return;
  const YAML::Node child = node[key];
  if (child.IsDefined()) OptionsReader(source, path + key, child).ReadInto(value);
}

// Reads node[key], which must be present.
template <class T>
void ReadRequired(const std::string& source, const YAML::Node& node, const char* key, T* value) {
  if (!IsMap(node) || !node[key].IsDefined()) {
    ThrowInputError(source, ": missing key '", key, "'", kWhatToDo);
  }
  OptionsReader(source, key, node[key]).ReadInto(value);
}

// The ray sampling of the last stage of a legacy checkpoint's solver config
// text: `defaults:` overridden by the last entry of `stages:`; keys absent
// from both keep TrainingSampling's defaults (the solver's stage defaults).
// Not recorded when the text has no stages.
std::optional<TrainingSampling> LegacyTrainingSampling(const YAML::Node& config,
                                                       const std::string& source) {
  if (!IsMap(config)) return std::nullopt;
  const YAML::Node stages = config["stages"];
  if (!IsSequence(stages) || stages.size() == 0) return std::nullopt;
  TrainingSampling s;
  const std::string last = "stages[" + std::to_string(stages.size() - 1) + "].";
  const std::vector<std::pair<std::string, YAML::Node>> layers = {
      {"defaults.", config["defaults"]}, {last, stages[stages.size() - 1]}};
  for (const auto& [path, stage] : layers) {
    if (!IsMap(stage)) continue;
    ReadOptional(source, path, stage, "samples_per_ray", &s.samples_per_ray);
    const YAML::Node sampling = stage["sampling"];
    ReadOptional(source, path + "sampling.", sampling, "near_far_margin", &s.near_far_margin);
    ReadOptional(source, path + "sampling.", sampling, "importance_depth", &s.importance_depth);
    ReadOptional(source, path + "sampling.", sampling, "clip_to_box", &s.clip_to_box);
    ReadOptional(source, path + "sampling.", sampling, "clip_margin", &s.clip_margin);
    ReadOptional(source, path + "sampling.", sampling, "importance_samples", &s.importance_samples);
    ReadOptional(source, path + "sampling.", sampling, "min_sdf_sample", &s.min_sdf_sample);
  }
  return s;
}

void WriteVector3(YAML::Emitter& out, const Eigen::Vector3d& v) {
  out << YAML::Flow << YAML::BeginSeq;
  for (int k = 0; k < 3; ++k) out << FormatDouble(v[k]);
  out << YAML::EndSeq;
}

// node[key], 3 numbers.
Eigen::Vector3d ReadVector3(const std::string& source, const YAML::Node& node, const char* key) {
  std::vector<double> v;
  ReadRequired(source, node, key, &v);
  if (v.size() != 3) {
    ThrowInputError(source, ": key '", key, "': expected 3 numbers, got ", v.size(), kWhatToDo);
  }
  return Eigen::Vector3d(v[0], v[1], v[2]);
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

  ModelOptions options = model.options();  // the field lists take non-const references
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kModelFileFormat;
  out << YAML::Key << "parameters" << YAML::Value << count;
  out << YAML::Key << "params_checksum" << YAML::Value << params_checksum;
  out << YAML::Key << "scene_scale" << YAML::Value << FormatDouble(model.scene_scale());
  out << YAML::Key << "canonical_origin" << YAML::Value;
  WriteVector3(out, model.canonical_origin());
  out << YAML::Key << "options" << YAML::Value;
  OptionsWriter(&out).WriteStruct(options);
  if (model.canonical_bounds()) {
    out << YAML::Key << "canonical_bounds" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "min" << YAML::Value;
    WriteVector3(out, model.canonical_bounds()->min());
    out << YAML::Key << "max" << YAML::Value;
    WriteVector3(out, model.canonical_bounds()->max());
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
YAML::Node LoadModelYaml(const std::string& dir, const std::string& yaml_path, bool* legacy) {
  if (!PathExists(yaml_path)) {
    ThrowInputError(dir, ": not a model folder (no model.yaml)", kWhatToDo);
  }
  YAML::Node root;
  try {
    root = YAML::Load(ReadRegularFile(yaml_path, kMaxTextFileBytes, kWhatToDo));
  } catch (const YAML::Exception& e) {
    ThrowInputError(yaml_path, ": not valid YAML (", e.what(), "): the file is damaged", kWhatToDo);
  }
  if (!IsMap(root)) {
    ThrowInputError(yaml_path,
                    ": expected a map of keys (format, parameters, ...): the file is "
                    "damaged",
                    kWhatToDo);
  }
  std::string format;
  ReadRequired(yaml_path, root, "format", &format);
  *legacy = format == kLegacyCheckpointFormat;
  if (!*legacy && format != kModelFileFormat) {
    ThrowInputError(yaml_path, ": unknown model format '", format, "' (this banmo reads ",
                    kModelFileFormat, " and ", kLegacyCheckpointFormat,
                    "); read it with the banmo that wrote it, or solve again with this one");
  }
  if (!*legacy) {
    CheckKnownKeys(
        yaml_path, "", root,
        {"format", "parameters", "params_checksum", "scene_scale", "canonical_origin", "options",
         "canonical_bounds", "training_sampling", "root_correction", "videos"});
    if (IsMap(root["training_sampling"])) {
      CheckKnownKeys(yaml_path, "training_sampling.", root["training_sampling"],
                     {"samples_per_ray", "near_far_margin", "importance_depth", "clip_to_box",
                      "clip_margin", "importance_samples", "min_sdf_sample"});
    }
    if (IsMap(root["canonical_bounds"])) {
      CheckKnownKeys(yaml_path, "canonical_bounds.", root["canonical_bounds"], {"min", "max"});
    }
    if (root["videos"].IsSequence()) {
      for (std::size_t v = 0; v < root["videos"].size(); ++v) {
        if (!IsMap(root["videos"][v])) continue;
        CheckKnownKeys(yaml_path, "videos[" + std::to_string(v) + "].", root["videos"][v],
                       {"frames", "width", "height", "intrinsics"});
      }
    }
  }
  return root;
}

// The model options and training sampling of a legacy checkpoint: the
// config's model section, the sizes those of model_size (absent before
// automatic sizing existed).
void ReadLegacyOptions(const std::string& yaml_path, const YAML::Node& root, ModelOptions* options,
                       std::optional<TrainingSampling>* sampling) {
  std::string config_text;
  ReadRequired(yaml_path, root, "config", &config_text);
  const std::string config_source = yaml_path + " (config)";
  YAML::Node config;
  try {
    config = YAML::Load(config_text);
  } catch (const YAML::Exception& e) {
    ThrowInputError(config_source, ": not valid YAML (", e.what(), ")", kWhatToDo);
  }
  if (IsMap(config) && config["model"].IsDefined()) {
    OptionsReader(config_source, "model", config["model"]).ReadInto(options);
  }
  const YAML::Node size = root["model_size"];
  if (size.IsDefined()) {
    ReadRequired(yaml_path + " (model_size)", size, "num_bones", &options->num_bones);
    ReadRequired(yaml_path + " (model_size)", size, "sdf_width", &options->field.sdf_width);
    ReadRequired(yaml_path + " (model_size)", size, "color_width", &options->field.color_width);
  }
  *sampling = LegacyTrainingSampling(config, config_source);
}

// The model options (key 'options') and the optional training_sampling.
void ReadOptions(const std::string& yaml_path, const YAML::Node& root, ModelOptions* options,
                 std::optional<TrainingSampling>* sampling) {
  const YAML::Node node = root["options"];
  if (!node.IsDefined()) ThrowInputError(yaml_path, ": missing key 'options'", kWhatToDo);
  OptionsReader(yaml_path, "options", node).ReadInto(options);
  const YAML::Node s = root["training_sampling"];
  if (s.IsDefined()) {
    TrainingSampling t;
    const std::string source = yaml_path + " (training_sampling)";
    ReadRequired(source, s, "samples_per_ray", &t.samples_per_ray);
    ReadRequired(source, s, "near_far_margin", &t.near_far_margin);
    ReadRequired(source, s, "importance_depth", &t.importance_depth);
    if (s["clip_to_box"].IsDefined()) {
      ReadRequired(source, s, "clip_to_box", &t.clip_to_box);
      ReadRequired(source, s, "clip_margin", &t.clip_margin);
    }
    if (s["importance_samples"].IsDefined()) {
      ReadRequired(source, s, "importance_samples", &t.importance_samples);
    }
    if (s["min_sdf_sample"].IsDefined()) {
      ReadRequired(source, s, "min_sdf_sample", &t.min_sdf_sample);
    }
    // 1024: the stage configuration's limit (docs/robustness.md).
    if (t.samples_per_ray <= 0 || t.samples_per_ray > 1024 || !(t.near_far_margin >= 0) ||
        !(t.clip_margin >= 0) || t.importance_samples < 0 || t.importance_samples > 1024) {
      ThrowInputError(yaml_path,
                      ": key 'training_sampling': expected samples_per_ray in [1, 1024], "
                      "near_far_margin >= 0, clip_margin >= 0 and importance_samples in [0, 1024]",
                      kWhatToDo);
    }
    *sampling = t;
  }
}

// Frame counts and cameras of the videos (key 'videos').
void ReadVideos(const std::string& yaml_path, const YAML::Node& root, std::vector<int>* frames,
                std::vector<PinholeCamera>* cameras) {
  const YAML::Node videos = root["videos"];
  if (!IsSequence(videos)) {
    ThrowInputError(yaml_path, ": key 'videos': expected a list of videos", kWhatToDo);
  }
  for (size_t v = 0; v < videos.size(); ++v) {
    const std::string source = yaml_path + " (videos[" + std::to_string(v) + "])";
    int count = 0;
    PinholeCamera cam;
    ReadRequired(source, videos[v], "frames", &count);
    ReadRequired(source, videos[v], "width", &cam.width);
    ReadRequired(source, videos[v], "height", &cam.height);
    std::vector<double> k;
    ReadRequired(source, videos[v], "intrinsics", &k);
    // The dataset format's limits (docs/robustness.md): 100000 frames per
    // video, sides of at most 16384 px.
    if (count < 0 || count > 100000 || cam.width <= 0 || cam.height <= 0 || cam.width > 16384 ||
        cam.height > 16384 || k.size() != 4) {
      ThrowInputError(source,
                      ": expected frames in [0, 100000], width and height in [1, 16384] and 4 "
                      "intrinsics",
                      kWhatToDo);
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
  const YAML::Node root = LoadModelYaml(dir, yaml_path, &legacy);
  ModelOptions options;
  std::optional<TrainingSampling> sampling;
  if (legacy) {
    ReadLegacyOptions(yaml_path, root, &options, &sampling);
  } else {
    ReadOptions(yaml_path, root, &options, &sampling);
  }
  try {
    options.Check();
  } catch (const InputError& e) {
    ThrowInputError(yaml_path, ": ", e.what(), kWhatToDo);
  }

  double scene_scale = 1.0;  // legacy checkpoints written before the key existed
  if (legacy) {
    ReadOptional(yaml_path, "", root, "scene_scale", &scene_scale);
  } else {
    ReadRequired(yaml_path, root, "scene_scale", &scene_scale);
  }
  if (!(scene_scale > 0 && std::isfinite(scene_scale))) {
    ThrowInputError(yaml_path, ": key 'scene_scale': expected a finite number > 0, got ",
                    scene_scale, kWhatToDo);
  }
  uint64_t expected_count = 0;
  ReadRequired(yaml_path, root, "parameters", &expected_count);
  std::string params_checksum;
  if (!legacy) ReadOptional(yaml_path, "", root, "params_checksum", &params_checksum);
  std::string root_correction = "camera";  // files written before the key existed
  ReadOptional(yaml_path, "", root, "root_correction", &root_correction);
  if (root_correction != kRootCorrectionObjectSide && root_correction != "camera") {
    ThrowInputError(yaml_path, ": key 'root_correction': expected '", kRootCorrectionObjectSide,
                    "' or 'camera', got '", root_correction, "'", kWhatToDo);
  }

  std::vector<int> frames;
  std::vector<PinholeCamera> cameras;
  ReadVideos(yaml_path, root, &frames, &cameras);
  auto model = std::make_unique<Model>(options, frames, cameras);
  model->set_scene_scale(scene_scale);
  if (sampling) model->set_training_sampling(*sampling);
  if (!legacy && root["canonical_origin"].IsDefined()) {  // zero in files written before it
    const Eigen::Vector3d c = ReadVector3(yaml_path, root, "canonical_origin");
    if (!c.allFinite()) {
      ThrowInputError(yaml_path, ": key 'canonical_origin': expected 3 finite numbers", kWhatToDo);
    }
    model->set_canonical_origin(c);
  }
  const YAML::Node bounds = root["canonical_bounds"];
  if (!legacy && bounds.IsDefined()) {
    const std::string source = yaml_path + " (canonical_bounds)";
    const Eigen::Vector3d lo = ReadVector3(source, bounds, "min");
    const Eigen::Vector3d hi = ReadVector3(source, bounds, "max");
    if (!IsValidBox(Eigen::AlignedBox3d(lo, hi))) {
      ThrowInputError(source, ": expected finite corners with max > min on every axis", kWhatToDo);
    }
    model->set_canonical_bounds(Eigen::AlignedBox3d(lo, hi));
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
