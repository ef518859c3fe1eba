#include "banmo/model/model.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

void ModelOptions::Check() const {
  field.Check("model.field");
  if (num_bones < 0 || num_bones > 256) {
    ThrowInputError("model.num_bones: expected 0..256, got ", num_bones);
  }
  if (!(init_bone_scale > 0)) ThrowInputError("model.init_bone_scale: expected > 0");
  if (!(init_beta > 0)) ThrowInputError("model.init_beta: expected > 0");
  if (scene_scale && !(*scene_scale > 0 && std::isfinite(*scene_scale))) {
    ThrowInputError("model.scene_scale: expected auto or a finite number > 0, got ", *scene_scale);
  }
  const std::string a = "model.auto_size.";
  if (auto_size.enabled && delta_skinning.enabled) {
    ThrowInputError(a,
                    "enabled: automatic sizing cannot be combined with delta skinning "
                    "(MLP_Delta's output layer has one unit per bone, so a bone split would "
                    "have to invent its weights); set model.delta_skinning.enabled: false");
  }
  // The bounds relative to the starting sizes matter only when enabled (a
  // disabled block with the defaults must not constrain num_bones).
  const int min_bones = auto_size.enabled ? num_bones : 0;
  if (auto_size.max_bones < min_bones || auto_size.max_bones > 256) {
    ThrowInputError(a, "max_bones: expected an integer in ",
                    auto_size.enabled ? "model.num_bones" : "0", "..256 (", min_bones,
                    "..256), got ", auto_size.max_bones);
  }
  for (size_t i = 0; i < auto_size.grow_at.size(); ++i) {
    const double f = auto_size.grow_at[i];
    if (!(f >= 0 && f <= 1)) {
      ThrowInputError(a, "grow_at[", i, "]: expected a fraction in [0, 1], got ", f);
    }
    if (i > 0 && !(f > auto_size.grow_at[i - 1])) {
      ThrowInputError(a, "grow_at[", i, "]: expected increasing fractions, got ", f, " after ",
                      auto_size.grow_at[i - 1]);
    }
  }
  if (!(auto_size.error_ratio >= 1) || !std::isfinite(auto_size.error_ratio)) {
    ThrowInputError(a, "error_ratio: expected a finite number >= 1, got ", auto_size.error_ratio);
  }
  if (auto_size.eval_rays <= 0) {
    ThrowInputError(a, "eval_rays: expected an integer > 0, got ", auto_size.eval_rays);
  }
  if (auto_size.max_width < 0 ||
      (auto_size.enabled && auto_size.max_width > 0 &&
       (auto_size.max_width < field.sdf_width || auto_size.max_width < field.color_width))) {
    ThrowInputError(a,
                    "max_width: expected 0 (widths fixed) or an integer >= model.field.sdf_width "
                    "and color_width (",
                    std::max(field.sdf_width, field.color_width), "), got ", auto_size.max_width);
  }
  const RootSmoothingOptions& rs = root_init_smoothing;
  if (!(rs.acceleration_deg > 0) || !std::isfinite(rs.acceleration_deg)) {
    ThrowInputError(
        "model.root_init_smoothing.acceleration_deg: expected a finite number > 0, got ",
        rs.acceleration_deg);
  }
  if (!(rs.robust_sigmas > 0) || !std::isfinite(rs.robust_sigmas)) {
    ThrowInputError("model.root_init_smoothing.robust_sigmas: expected a finite number > 0, got ",
                    rs.robust_sigmas);
  }
  if (root_init_registration.references < 16 || root_init_registration.references > 5000) {
    ThrowInputError(
        "model.root_init_registration.references: expected an integer in [16, 5000], got ",
        root_init_registration.references);
  }
  if (delta_skinning.enabled) {
    delta_skinning.Check();
    if (num_bones < 1) {
      ThrowInputError("model.delta_skinning.enabled: delta skinning needs num_bones >= 1");
    }
  }
}

Model::Model(const ModelOptions& options, const std::vector<int>& frames_per_video,
             const std::vector<PinholeCamera>& cameras)
    : options_(options), field_(std::make_unique<CanonicalField>(options.field)) {
  options_.Check();
  CHECK_EQ(frames_per_video.size(), cameras.size());
  sdf_.resize(field_->SdfParameterSize());
  color_.resize(field_->ColorParameterSize());
  embedding_.resize(field_->EmbeddingParameterSize());
  field_->InitializeParameters(options.seed, sdf_.data(), color_.data(), embedding_.data());
  log_beta_ = std::log(options.init_beta);
  scene_scale_ = options.scene_scale.value_or(1.0);

  // Bones on a Fibonacci sphere of half the initial SDF radius.
  const int B = options.num_bones;
  std::vector<Eigen::Vector3d> centres(B);
  const double radius = 0.5 * options.field.init_sphere_radius;
  for (int b = 0; b < B; ++b) {
    const double y = B == 1 ? 0.0 : 1.0 - 2.0 * (b + 0.5) / B;
    const double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    const double phi = b * M_PI * (3.0 - std::sqrt(5.0));
    centres[b] = radius * Eigen::Vector3d(r * std::cos(phi), y, r * std::sin(phi));
  }
  bones_.resize(kBoneSize * B);
  InitializeBones(centres, options.init_bone_scale, bones_.data());

  // Delta skinning: MLP with a zero output layer, small random pose codes
  // (portable: uniform draws from the raw mt19937 stream, scaled to the
  // requested standard deviation).
  std::mt19937 code_rng(options.seed + 7919u);
  auto random_code = [&](std::vector<double>* code) {
    const int P = options.delta_skinning.pose_code_dim;
    code->resize(P);
    for (int k = 0; k < P; ++k) {
      const double u = (static_cast<double>(code_rng()) + 0.5) / 4294967296.0;  // (0, 1)
      (*code)[k] = options.delta_skinning.code_init_std * std::sqrt(3.0) * (2.0 * u - 1.0);
    }
  };
  if (options.delta_skinning.enabled) {
    delta_ = std::make_unique<DeltaSkinning>(options.delta_skinning, B);
    delta_params_.resize(delta_->NumParameters());
    delta_->InitializeParameters(options.seed + 104729u, delta_params_.data());
    random_code(&rest_pose_code_);
  }

  videos_.resize(frames_per_video.size());
  for (size_t v = 0; v < videos_.size(); ++v) {
    videos_[v].camera = cameras[v];
    videos_[v].intrinsics = cameras[v].intrinsics;
    videos_[v].appearance.assign(options.field.appearance_code_dim, 0.0);
    videos_[v].frames.resize(frames_per_video[v]);
    for (auto& f : videos_[v].frames) {
      f.bones_t.resize(kPoseSize * B);
      for (int b = 0; b < B; ++b) PoseSetIdentity(f.bones_t.data() + kPoseSize * b);
      if (delta_) random_code(&f.pose_code);
    }
  }
}

void Model::set_scene_scale(double s) {
  CHECK(s > 0 && std::isfinite(s)) << "scene scale " << s;
  scene_scale_ = s;
}

bool Model::DeltaSkinningIsNonZero() const {
  return delta_ != nullptr && !delta_->IsZero(delta_params_.data());
}

Pose Model::RootPose(int v, int t) const {
  const FrameParameters& f = frame(v, t);
  Pose out;
  PoseCompose(f.root_init.data(), f.root_delta.data(), out.data());
  return out;
}

template <class Self, class Fn>
void Model::VisitBlocks(Self& self, const Fn& fn) {
  fn("sdf", self.sdf_.data(), self.sdf_size());
  fn("color", self.color_.data(), self.color_size());
  fn("embedding", self.embedding_.data(), self.embedding_size());
  fn("log_beta", &self.log_beta_, 1);
  fn("bones", self.bones_.data(), self.bones_size());
  if (self.delta_) {
    fn("delta_skinning", self.delta_params_.data(), self.delta_skinning_size());
    fn("rest_pose_code", self.rest_pose_code_.data(), self.pose_code_size());
  }
  for (size_t v = 0; v < self.videos_.size(); ++v) {
    auto& video = self.videos_[v];
    const std::string name = "video" + std::to_string(v);
    fn(name + "/intrinsics", video.intrinsics.data(), 4);
    fn(name + "/appearance", video.appearance.data(), self.appearance_size());
    for (size_t t = 0; t < video.frames.size(); ++t) {
      auto& f = video.frames[t];
      const std::string frame = name + "/frame" + std::to_string(t);
      fn(frame + "/root_delta", f.root_delta.data(), kPoseSize);
      fn(frame + "/root_init", f.root_init.data(), kPoseSize);
      fn(frame + "/bones_t", f.bones_t.data(), static_cast<int>(f.bones_t.size()));
      if (self.delta_) fn(frame + "/pose_code", f.pose_code.data(), self.pose_code_size());
    }
  }
}

std::optional<ParameterGroup> Model::BlockGroup(const std::string& name) {
  using G = ParameterGroup;
  // The last path component of VisitBlocks' names.
  static const std::pair<const char*, G> kGroups[] = {{"sdf", G::kSdf},
                                                      {"color", G::kColor},
                                                      {"embedding", G::kEmbedding},
                                                      {"log_beta", G::kLogBeta},
                                                      {"bones", G::kBones},
                                                      {"delta_skinning", G::kDeltaSkinning},
                                                      {"rest_pose_code", G::kDeltaSkinning},
                                                      {"intrinsics", G::kIntrinsics},
                                                      {"appearance", G::kAppearance},
                                                      {"root_delta", G::kRoot},
                                                      {"bones_t", G::kBonesT},
                                                      {"pose_code", G::kPoseCode}};
  const size_t slash = name.rfind('/');
  const std::string last = slash == std::string::npos ? name : name.substr(slash + 1);
  for (const auto& [block, group] : kGroups) {
    if (last == block) return group;
  }
  return std::nullopt;
}

void Model::ForEachBlock(
    const std::function<void(const std::string& name, double* data, int size)>& fn) {
  VisitBlocks(*this, fn);
}

void Model::ForEachBlock(
    const std::function<void(const std::string& name, const double* data, int size)>& fn) const {
  VisitBlocks(*this, fn);
}

void Model::SetBones(int num_bones, const std::vector<double>& bones) {
  CHECK(delta_ == nullptr) << "the bone count cannot change with delta skinning";
  CHECK_GE(num_bones, 0);
  CHECK_EQ(static_cast<int>(bones.size()), kBoneSize * num_bones);
  const int old_bones = options_.num_bones;
  options_.num_bones = num_bones;
  bones_ = bones;
  for (VideoParameters& video : videos_) {
    for (FrameParameters& f : video.frames) {
      f.bones_t.resize(kPoseSize * num_bones);
      for (int b = old_bones; b < num_bones; ++b) PoseSetIdentity(f.bones_t.data() + kPoseSize * b);
    }
  }
}

void Model::SetFieldWidths(int sdf_width, int color_width, std::vector<double> sdf,
                           std::vector<double> color) {
  CanonicalFieldOptions field = options_.field;
  field.sdf_width = sdf_width;
  field.color_width = color_width;
  auto next = std::make_unique<CanonicalField>(field);
  CHECK_EQ(static_cast<int>(sdf.size()), next->SdfParameterSize());
  CHECK_EQ(static_cast<int>(color.size()), next->ColorParameterSize());
  CHECK_EQ(next->EmbeddingParameterSize(), embedding_size());
  const double alpha = field_->position_encoding().annealing_alpha();
  if (alpha >= 0) next->SetAnnealing(alpha);
  options_.field = field;
  field_ = std::move(next);
  sdf_ = std::move(sdf);
  color_ = std::move(color);
}

}  // namespace banmo
