// YAML <-> SolverConfig. Every struct lists its fields once (VisitFields);
// the YAML walker's reader and writer (util/yaml.h) both walk those lists,
// so a field is read and written under the same key by construction.
#include "banmo/optim/config.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "banmo/model/model_options_fields.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"
#include "banmo/util/input_file.h"
#include "banmo/util/logging.h"
#include "banmo/util/yaml.h"

namespace banmo {

LossesConfig::LossesConfig() {
  for (const LossTermInfo& info : kLossTable) (*this)[info.term].weight = info.default_weight;
}

RayLossWeights LossesConfig::RayWeights() const {
  RayLossWeights w;
  for (int t = 0; t < kNumRayTerms; ++t) w[RayTerm(t)] = terms[t].weight;
  return w;
}

// ---- Field lists (keys = field names). ----

// In namespace banmo, where util/yaml.h finds them (argument-dependent
// lookup). The model section: model/model_options_fields.h.

template <class V>
void VisitFields(V& v, RobustLossConfig& o) {
  v("type", o.type);
  v("scale", o.scale);
}

template <class V>
void VisitFields(V& v, LossConfig& o) {
  v("weight", o.weight);
  v("robust", o.robust);
}

template <class V>
void VisitFields(V& v, LossesConfig& o) {
  for (const LossTermInfo& info : kLossTable) v(info.key, o[info.term]);
  v("bone_inside_margin", o.bone_inside_margin);
  v("feature_render_embedding_only", o.feature_render_embedding_only);
}

template <class V>
void VisitFields(V& v, AdamConfig& o) {
  v("lr", o.lr);
  v("beta1", o.beta1);
  v("beta2", o.beta2);
  v("epsilon", o.epsilon);
  v("weight_decay", o.weight_decay);
  v("schedule", o.schedule);
  v("warmup_fraction", o.warmup_fraction);
  v("final_lr_fraction", o.final_lr_fraction);
  v("pose_lr_scale", o.pose_lr_scale);
  v("bone_lr_scale", o.bone_lr_scale);
  v("beta_lr_scale", o.beta_lr_scale);
  v("intrinsics_lr_scale", o.intrinsics_lr_scale);
  v("bone_basis", o.bone_basis);
  v("root_basis", o.root_basis);
}

template <class V>
void VisitFields(V& v, LmConfig& o) {
  v("max_cg_iterations", o.max_cg_iterations);
  v("initial_radius", o.initial_radius);
  v("max_radius", o.max_radius);
  v("linear_solver", o.linear_solver);
  v("iterations_per_batch", o.iterations_per_batch);
}

template <class V>
void VisitFields(V& v, SamplingConfig& o) {
  v("foreground_fraction", o.foreground_fraction);
  v("boundary_fraction", o.boundary_fraction);
  v("active_fraction", o.active_fraction);
  v("crop_scale", o.crop_scale);
  v("importance_depth", o.importance_depth);
  v("importance_samples", o.importance_samples);
  v("min_sdf_sample", o.min_sdf_sample);
  v("near_far_margin", o.near_far_margin);
  v("clip_to_box", o.clip_to_box);
  v("clip_margin", o.clip_margin);
  v("flow_gaps", o.flow_gaps);
  v("eikonal_points", o.eikonal_points);
  v("match_grid_points", o.match_grid_points);
  v("match_top_k", o.match_top_k);
  v("frames_per_batch", o.frames_per_batch);
  v("unbiased_silhouette", o.unbiased_silhouette);
}

template <class V>
void VisitFields(V& v, ScheduleConfig& o) {
  v("bone_reinit_at", o.bone_reinit_at);
  v("bone_reinit_keep_motion", o.bone_reinit_keep_motion);
  v("bone_sites", o.bone_sites);
  v("freeze_after_reinit", o.freeze_after_reinit);
  v("bounds_refresh_every", o.bounds_refresh_every);
  v("bounds_refresh_max_mask_loss", o.bounds_refresh_max_mask_loss);
  v("anneal_end_fraction", o.anneal_end_fraction);
  v("delta_skinning_from", o.delta_skinning_from);
  v("root_free_from", o.root_free_from);
  v("unbiased_silhouette_from", o.unbiased_silhouette_from);
  v("neus_from", o.neus_from);
}

template <class V>
void VisitFields(V& v, PoseSolveConfig& o) {
  v("at", o.at);
  v("every", o.every);
  v("bones", o.bones);
  v("rays", o.rays);
  v("iterations", o.iterations);
  v("search_ratio", o.search_ratio);
  v("search_rotations", o.search_rotations);
  v("search_keep", o.search_keep);
  v("featureless_only", o.featureless_only);
}

template <class V>
void VisitFields(V& v, BoneRegistrationFinalWeights& o) {
  v("match_weight", o.match_weight);
  v("mask_weight", o.mask_weight);
  v("coverage_weight", o.coverage_weight);
}

template <class V>
void VisitFields(V& v, BoneRegistrationConfig& o) {
  v("at", o.at);
  v("resolution", o.resolution);
  v("vertices", o.vertices);
  v("match_pixels", o.match_pixels);
  v("match_weight", o.match_weight);
  v("huber_px", o.huber_px);
  v("joint_weight", o.joint_weight);
  v("joint_min_weight", o.joint_min_weight);
  v("joint_points", o.joint_points);
  v("smooth_weight", o.smooth_weight);
  v("rest_weight", o.rest_weight);
  v("visible_tolerance", o.visible_tolerance);
  v("iterations", o.iterations);
  v("mask_weight", o.mask_weight);
  v("mask_points", o.mask_points);
  v("coverage_weight", o.coverage_weight);
  v("coverage_pixels", o.coverage_pixels);
  v("coverage_rounds", o.coverage_rounds);
  v("start", o.start);
  v("after_last_batch", o.after_last_batch);
}

template <class V>
void VisitFields(V& v, StageConfig& o) {
  v("name", o.name);
  v("batches", o.batches);
  v("step_rule", o.step_rule);
  v("batch_rays", o.batch_rays);
  v("samples_per_ray", o.samples_per_ray);
  v("losses", o.losses);
  v("constant", o.constant);
  v("adam", o.adam);
  v("lm", o.lm);
  v("sampling", o.sampling);
  v("schedule", o.schedule);
  v("pose_solve", o.pose_solve);
  v("bone_registration", o.bone_registration);
  v("bone_steps_about_centres", o.bone_steps_about_centres);
  v("bone_steps_articulated", o.bone_steps_articulated);
  v("checkpoint_every", o.checkpoint_every);
  v("log_every", o.log_every);
}

namespace {

// ---- Reading. ----

// The line a checked key comes from: the key itself, else the same key in
// `defaults:` (stage keys inherited from there), else its nearest parent.
int LineOfKey(std::string key, const std::map<std::string, int>& lines) {
  while (!key.empty()) {
    auto it = lines.find(key);
    if (it != lines.end()) return it->second;
    if (key.rfind("stages[", 0) == 0) {
      const size_t close = key.find(']');
      if (close != std::string::npos) {
        const std::string rest = key.substr(close + 1);
        it = lines.find(rest.empty() ? "defaults" : "defaults" + rest);
        if (it != lines.end()) return it->second;
      }
    }
    const size_t cut = key.find_last_of(".[");
    key = cut == std::string::npos ? std::string() : key.substr(0, cut);
  }
  return 0;
}

// The old key of StageConfig::batches, read as a deprecated alias.
constexpr const char* kOldBatchesKey = "iterations";

// A stage map (`defaults:` or `stages[i]`) with the deprecated key
// `iterations` renamed to `batches` (a warning names the key); both keys in
// one map are an error. Other maps are returned as they are.
YamlNode RenameDeprecatedStageKeys(const YamlNode& node) {
  if (!node.Has(kOldBatchesKey)) return node;
  const YamlNode old = node[kOldBatchesKey];
  if (node.Has("batches")) {
    ThrowInputError(node.source(), ": key '", old.path(), "'", old.LineNote(),
                    ": the old name of '", node["batches"].path(),
                    "', which is also given; keep only 'batches'");
  }
  LOG(WARNING) << node.source() << ": key '" << old.path() << "'" << old.LineNote()
               << " is deprecated: use 'batches' (the stage's minibatches; 'iterations' now "
                  "only counts solver iterations, e.g. lm.iterations_per_batch)";
  YAML::Node renamed(YAML::NodeType::Map);
  for (auto it = node.yaml().begin(); it != node.yaml().end(); ++it) {
    const bool is_old = it->first.IsScalar() && it->first.Scalar() == kOldBatchesKey;
    renamed[is_old ? YAML::Node("batches") : it->first] = it->second;
  }
  return node.WithNode(renamed);
}

// Small leaf structs on one line: rgb: {weight: 1, robust: {type: none, scale: 1}}.
struct ConfigLayout {
  template <class S>
  static constexpr bool kOneLine =
      std::is_same_v<S, LossConfig> || std::is_same_v<S, RobustLossConfig> ||
      std::is_same_v<S, PositionalEncodingOptions> ||
      std::is_same_v<S, BoneRegistrationFinalWeights>;
};

// ---- Checking. ----

// Limits of the configuration (docs/robustness.md): far above any useful
// value, low enough that memory stays bounded and steps stay finite.
constexpr int kMaxBatchRays = 1 << 16;
constexpr int kMaxSamplesPerRay = 1024;
constexpr long kMaxBatchSamples = 1L << 22;  // ~4M samples: a few GB of activations
constexpr double kMaxLearningRate = 100.0;
constexpr double kMaxLossWeight = 1e6;

using Checker = OptionChecker;

// The rules of a stage that span several of its sections.
void CheckStageRules(const Checker& c, const std::string& p, const StageConfig& s) {
  if (static_cast<long>(s.batch_rays) * (s.samples_per_ray + s.sampling.importance_samples) >
      kMaxBatchSamples) {
    c.Fail(p + ".batch_rays", "batch_rays x (samples_per_ray + sampling.importance_samples) = ",
           static_cast<long>(s.batch_rays) * (s.samples_per_ray + s.sampling.importance_samples),
           " samples per batch, expected at most ", kMaxBatchSamples);
  }
  ParameterGroupSet constant;
  for (size_t i = 0; i < s.constant.size(); ++i) {
    const std::string key = p + ".constant[" + std::to_string(i) + "]";
    if (constant.Contains(s.constant[i])) {
      c.Fail(key, "group '", EnumName(s.constant[i]), "' listed twice");
    }
    constant.Insert(s.constant[i]);
  }
  // The groups every model has (delta_skinning and pose_code exist only with
  // delta skinning, which alone is nothing to reconstruct).
  bool all_constant = true;
  for (const auto& [group, name] : EnumNames<ParameterGroup>::kNames) {
    if (group == ParameterGroup::kDeltaSkinning || group == ParameterGroup::kPoseCode) continue;
    all_constant = all_constant && constant.Contains(group);
  }
  const bool pose_solves = !s.pose_solve.at.empty() || s.pose_solve.every > 0;
  if (all_constant && !pose_solves) {
    c.Fail(p + ".constant",
           "every parameter group is constant and there is no pose solve (nothing to optimise)");
  }
  if (s.losses[LossTerm::kFlow].weight > 0 && s.sampling.flow_gaps.empty()) {
    c.Fail(p + ".sampling.flow_gaps", "expected at least one gap when losses.flow.weight > 0");
  }
  if (s.schedule.unbiased_silhouette_from < 1.0 &&
      !(s.sampling.foreground_fraction + s.sampling.boundary_fraction < 1.0)) {
    c.Fail(p + ".schedule.unbiased_silhouette_from",
           "needs sampling.foreground_fraction + sampling.boundary_fraction < 1 (most background "
           "pixels are never drawn at 1)");
  }

  const std::string q = p + ".pose_solve";
  if (pose_solves && constant.Contains(ParameterGroup::kRoot) && !s.pose_solve.bones) {
    c.Fail(q + (s.pose_solve.at.empty() ? ".every" : ".at"),
           "pose solves move the root poses, which this stage holds constant (set "
           "pose_solve.bones: true to solve the bone transforms alone)");
  }
  const bool solved_blocks_free =
      !constant.Contains(ParameterGroup::kRoot) ||
      (s.pose_solve.bones && !constant.Contains(ParameterGroup::kBonesT));
  if (s.step_rule == StepRule::kAlternate && !pose_solves && solved_blocks_free) {
    c.Fail(q + ".every",
           "step_rule alternate moves the per-frame root corrections (and with pose_solve.bones "
           "the bone transforms) only in pose solves: set pose_solve.every (for example 100) or "
           "pose_solve.at, or hold root constant");
  }
  if (!s.pose_solve.at.empty() && s.pose_solve.at.front() < s.schedule.root_free_from &&
      !constant.Contains(ParameterGroup::kRoot)) {
    c.Fail(q + ".at", "a pose solve at ", s.pose_solve.at.front(),
           " comes before schedule.root_free_from (", s.schedule.root_free_from,
           "), while the root poses are held constant");
  }

  const std::string r = p + ".bone_registration";
  const BoneRegistrationConfig& reg = s.bone_registration;
  if (!reg.at.empty() && constant.Contains(ParameterGroup::kBonesT)) {
    c.Fail(r + ".at",
           "a bone registration moves the bone transforms, which this stage holds "
           "constant (bones_t)");
  }
  const BoneRegistrationFinalWeights& last = reg.after_last_batch;
  const bool registers_last = std::any_of(reg.at.begin(), reg.at.end(),
                                          [&](double f) { return s.BatchAt(f) == s.batches; });
  if ((last.match_weight || last.mask_weight || last.coverage_weight) && !reg.at.empty() &&
      !registers_last) {
    c.Fail(r + ".after_last_batch",
           "weights for a registration after the stage's last batch, but no fraction in "
           "bone_registration.at registers there (1.0 does)");
  }
  if (s.bone_steps_articulated && s.bone_steps_about_centres) {
    c.Fail(p + ".bone_steps_articulated",
           "cannot be combined with bone_steps_about_centres (each sets how a bone transform "
           "steps): choose one");
  }
}

}  // namespace

void LossConfig::Check(const OptionChecker& c, const std::string& key) const {
  c.NonNegative(key + ".weight", weight);
  if (weight > kMaxLossWeight) {
    c.Fail(key + ".weight", "expected at most ", kMaxLossWeight, ", got ", weight);
  }
  c.Positive(key + ".robust.scale", robust.scale);
}

void LossesConfig::Check(const OptionChecker& c, const std::string& key) const {
  bool any_loss = false;
  for (const LossTermInfo& info : kLossTable) {
    const LossConfig& loss = (*this)[info.term];
    loss.Check(c, key + "." + info.key);
    any_loss = any_loss || loss.weight > 0;
  }
  if (!any_loss) c.Fail(key, "every loss weight is 0 (nothing to minimise)");
  c.NonNegative(key + ".bone_inside_margin", bone_inside_margin);
}

void AdamConfig::Check(const OptionChecker& c, const std::string& a) const {
  c.PositiveAtMost(a + ".lr", lr, kMaxLearningRate);
  if (!(beta1 >= 0 && beta1 < 1)) c.Fail(a + ".beta1", "expected a number in [0, 1), got ", beta1);
  if (!(beta2 >= 0 && beta2 < 1)) c.Fail(a + ".beta2", "expected a number in [0, 1), got ", beta2);
  c.Positive(a + ".epsilon", epsilon);
  c.NonNegative(a + ".weight_decay", weight_decay);
  c.Fraction(a + ".warmup_fraction", warmup_fraction);
  c.Fraction(a + ".final_lr_fraction", final_lr_fraction);
  c.PositiveAtMost(a + ".pose_lr_scale", pose_lr_scale, kMaxLearningRate);
  c.PositiveAtMost(a + ".bone_lr_scale", bone_lr_scale, kMaxLearningRate);
  c.PositiveAtMost(a + ".beta_lr_scale", beta_lr_scale, kMaxLearningRate);
  c.PositiveAtMost(a + ".intrinsics_lr_scale", intrinsics_lr_scale, kMaxLearningRate);
  c.NonNegative(a + ".bone_basis", bone_basis);
  c.NonNegative(a + ".root_basis", root_basis);
}

void LmConfig::Check(const OptionChecker& c, const std::string& m) const {
  c.Positive(m + ".max_cg_iterations", max_cg_iterations);
  c.Positive(m + ".initial_radius", initial_radius);
  c.Positive(m + ".max_radius", max_radius);
  if (max_radius < initial_radius) {
    c.Fail(m + ".max_radius", "expected >= lm.initial_radius (", initial_radius, "), got ",
           max_radius);
  }
  c.Positive(m + ".iterations_per_batch", iterations_per_batch);
}

void SamplingConfig::Check(const OptionChecker& c, const std::string& g) const {
  c.Fraction(g + ".foreground_fraction", foreground_fraction);
  c.Fraction(g + ".boundary_fraction", boundary_fraction);
  if (foreground_fraction + boundary_fraction > 1.0) {
    c.Fail(g + ".boundary_fraction", "expected <= 1 - sampling.foreground_fraction (",
           1.0 - foreground_fraction, "), got ", boundary_fraction);
  }
  c.Fraction(g + ".active_fraction", active_fraction);
  if (crop_scale != 0.0 && !(crop_scale >= 1.0 && std::isfinite(crop_scale))) {
    c.Fail(g + ".crop_scale", "expected 0 (the whole image) or a finite number >= 1, got ",
           crop_scale);
  }
  c.NonNegative(g + ".importance_samples", importance_samples);
  if (importance_samples > kMaxSamplesPerRay) {
    c.Fail(g + ".importance_samples", "expected at most ", kMaxSamplesPerRay, ", got ",
           importance_samples);
  }
  if (importance_samples > 0 && !importance_depth) {
    c.Fail(g + ".importance_samples", "needs sampling.importance_depth: true (got ",
           importance_samples, " added samples without the importance pass)");
  }
  if (min_sdf_sample && !importance_depth) {
    c.Fail(g + ".min_sdf_sample",
           "needs sampling.importance_depth: true (the minimum comes from the importance pass's "
           "first rendering)");
  }
  c.NonNegative(g + ".near_far_margin", near_far_margin);
  c.NonNegative(g + ".clip_margin", clip_margin);
  for (size_t i = 0; i < flow_gaps.size(); ++i) {
    c.Positive(g + ".flow_gaps[" + std::to_string(i) + "]", flow_gaps[i]);
  }
  c.PositiveAtMost(g + ".eikonal_points", eikonal_points, kMaxBatchRays);
  c.PositiveAtMost(g + ".match_grid_points", match_grid_points, kMaxBatchRays);
  c.Positive(g + ".match_top_k", match_top_k);
  c.NonNegative(g + ".frames_per_batch", frames_per_batch);
  if (unbiased_silhouette && !(foreground_fraction + boundary_fraction < 1.0)) {
    c.Fail(g + ".unbiased_silhouette",
           "needs sampling.foreground_fraction + sampling.boundary_fraction < 1 (most background "
           "pixels are never drawn at 1)");
  }
  if (match_top_k > match_grid_points) {
    c.Fail(g + ".match_top_k", "expected <= sampling.match_grid_points (", match_grid_points,
           "), got ", match_top_k);
  }
}

void ScheduleConfig::Check(const OptionChecker& c, const std::string& h, int batches) const {
  c.BatchFractions(h + ".bone_reinit_at", bone_reinit_at, batches);
  c.Fraction(h + ".freeze_after_reinit", freeze_after_reinit);
  if (freeze_after_reinit > 0.0 && bone_reinit_at.empty()) {
    c.Fail(h + ".freeze_after_reinit",
           "needs schedule.bone_reinit_at (the freeze follows each re-initialisation)");
  }
  c.NonNegative(h + ".bounds_refresh_every", bounds_refresh_every);
  c.NonNegative(h + ".bounds_refresh_max_mask_loss", bounds_refresh_max_mask_loss);
  c.Fraction(h + ".anneal_end_fraction", anneal_end_fraction);
  c.NonNegative(h + ".delta_skinning_from", delta_skinning_from);
  c.Fraction(h + ".root_free_from", root_free_from);
  c.NonNegative(h + ".unbiased_silhouette_from", unbiased_silhouette_from);
  c.NonNegative(h + ".neus_from", neus_from);
}

void PoseSolveConfig::Check(const OptionChecker& c, const std::string& q, int batches) const {
  c.BatchFractions(q + ".at", at, batches);
  c.NonNegative(q + ".every", every);
  c.Positive(q + ".rays", rays);
  c.Positive(q + ".iterations", iterations);
  c.NonNegative(q + ".search_ratio", search_ratio);
  c.Positive(q + ".search_rotations", search_rotations);
  c.Positive(q + ".search_keep", search_keep);
  if (search_keep > search_rotations) {
    c.Fail(q + ".search_keep", "expected <= pose_solve.search_rotations (", search_rotations,
           "), got ", search_keep);
  }
}

void StageConfig::Check(const OptionChecker& c, const std::string& p) const {
  if (name.empty()) c.Fail(p + ".name", "expected a non-empty name");
  c.Positive(p + ".batches", batches);
  c.PositiveAtMost(p + ".batch_rays", batch_rays, kMaxBatchRays);
  c.PositiveAtMost(p + ".samples_per_ray", samples_per_ray, kMaxSamplesPerRay);
  losses.Check(c, p + ".losses");
  adam.Check(c, p + ".adam");
  lm.Check(c, p + ".lm");
  sampling.Check(c, p + ".sampling");
  schedule.Check(c, p + ".schedule", batches);
  pose_solve.Check(c, p + ".pose_solve", batches);
  bone_registration.Check(c, p + ".bone_registration");
  c.NonNegative(p + ".checkpoint_every", checkpoint_every);
  c.NonNegative(p + ".log_every", log_every);
  CheckStageRules(c, p, *this);
}

SamplingConfig SamplingAt(const StageConfig& stage, double fraction) {
  SamplingConfig sampling = stage.sampling;
  const double from = stage.schedule.unbiased_silhouette_from;
  sampling.unbiased_silhouette = sampling.unbiased_silhouette || (from < 1.0 && fraction >= from);
  return sampling;
}

SolverConfig LoadSolverConfig(const std::string& path) {
  return ParseSolverConfig(ReadRegularFile(path, kMaxTextFileBytes, " (the config file)"), path);
}

SolverConfig ParseSolverConfig(const std::string& yaml_text, const std::string& source) {
  const YamlNode root = YamlNode::Parse(yaml_text, source);
  if (root.IsNull()) {
    ThrowInputError(source, ": empty config (expected a map with a 'stages' list)");
  }
  root.CheckKeys({"model", "defaults", "stages", "seed", "threads"});

  SolverConfig config;
  root.ReadIfPresent("model", &config.model);
  root.ReadIfPresent("seed", &config.seed);
  root.ReadIfPresent("threads", &config.threads);

  StageConfig base;
  if (root.Has("defaults")) RenameDeprecatedStageKeys(root["defaults"]).ReadStruct(&base);

  const YamlNode stages = root["stages"];
  if (stages.IsNull()) {
    ThrowInputError(source, ": key 'stages': expected a non-empty list of stages");
  }
  if (!stages.IsSequence()) stages.TypeError("a list of stages");
  for (size_t i = 0; i < stages.size(); ++i) {
    StageConfig stage = base;
    RenameDeprecatedStageKeys(stages[i]).ReadStruct(&stage);
    config.stages.push_back(std::move(stage));
  }
  try {
    CheckSolverConfig(config, source);
  } catch (const InputError& e) {
    // Add the line of the offending key: "<source>: <key>[: ]..." -> "... (line N)".
    const std::string message = e.what();
    const size_t begin = source.size() + 2;
    const size_t end = message.find_first_of(": ", begin);
    const int line = message.rfind(source + ": ", 0) == 0 && end != std::string::npos
                         ? LineOfKey(message.substr(begin, end - begin), root.KeyLines())
                         : 0;
    if (line > 0) ThrowInputError(message, " (line ", line, ")");
    throw;
  }
  return config;
}

std::string SolverConfigToYaml(const SolverConfig& config) {
  YAML::Emitter out;
  out << YAML::Comment("banmo solver config, resolved (every key; see docs/config.md)");
  out << YAML::BeginMap;
  YamlWriter<ConfigLayout> writer(&out);
  writer("model", config.model);
  writer("seed", config.seed);
  writer("threads", config.threads);
  writer("stages", config.stages);
  out << YAML::EndMap;
  CHECK(out.good()) << "YAML emitter: " << out.GetLastError();
  return std::string(out.c_str()) + "\n";
}

void CheckSolverConfig(const SolverConfig& config, const std::string& source) {
  const Checker c(source);
  const ModelOptions& m = config.model;
  try {
    m.field.Check("model.field");  // names the key: "model.field.sdf_width must be ..."
  } catch (const InputError& e) {
    ThrowInputError(source, ": ", e.what());
  }
  if (m.num_bones < 0 || m.num_bones > 256) {
    c.Fail("model.num_bones", "expected an integer in 0..256, got ", m.num_bones);
  }
  c.Positive("model.init_bone_scale", m.init_bone_scale);
  c.Positive("model.init_beta", m.init_beta);
  if (m.scene_scale && !(*m.scene_scale > 0 && std::isfinite(*m.scene_scale))) {
    c.Fail("model.scene_scale", "expected auto or a finite number > 0, got ", *m.scene_scale);
  }
  try {
    m.Check();  // the model's own constraints (names the key)
  } catch (const InputError& e) {
    ThrowInputError(source, ": ", e.what());
  }
  c.NonNegative("threads", config.threads);
  if (config.stages.empty()) c.Fail("stages", "expected a non-empty list of stages");
  for (size_t i = 0; i < config.stages.size(); ++i) {
    const std::string p = "stages[" + std::to_string(i) + "]";
    config.stages[i].Check(c, p);
    if (config.stages[i].schedule.delta_skinning_from < 1.0 && !m.delta_skinning.enabled) {
      c.Fail(p + ".schedule.delta_skinning_from",
             "delta skinning is switched on here but the model has none: set "
             "model.delta_skinning.enabled: true (or delta_skinning_from >= 1), got ",
             config.stages[i].schedule.delta_skinning_from);
    }
  }
  if (m.auto_size.enabled) {
    // The grow steps run in the first stage (optim/auto_size.h).
    c.BatchFractions("model.auto_size.grow_at", m.auto_size.grow_at, config.stages[0].batches);
  }
}

}  // namespace banmo
