#include "banmo/model/model.h"

#include <cmath>
#include <random>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

void ModelOptions::Check() const {
  if (!field.Check()) ThrowInputError("model.field: invalid canonical field options");
  if (num_bones < 0 || num_bones > 256) {
    ThrowInputError("model.num_bones: expected 0..256, got ", num_bones);
  }
  if (!(init_bone_scale > 0)) ThrowInputError("model.init_bone_scale: expected > 0");
  if (!(init_beta > 0)) ThrowInputError("model.init_beta: expected > 0");
  if (scene_scale && !(*scene_scale > 0 && std::isfinite(*scene_scale))) {
    ThrowInputError("model.scene_scale: expected auto or a finite number > 0, got ", *scene_scale);
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
  PoseCompose(f.root_delta.data(), f.root_init.data(), out.data());
  return out;
}

void Model::ForEachBlock(
    const std::function<void(const std::string& name, double* data, int size)>& fn) {
  fn("sdf", sdf_.data(), sdf_size());
  fn("color", color_.data(), color_size());
  fn("embedding", embedding_.data(), embedding_size());
  fn("log_beta", &log_beta_, 1);
  fn("bones", bones_.data(), bones_size());
  if (delta_) {
    fn("delta_skinning", delta_params_.data(), delta_skinning_size());
    fn("rest_pose_code", rest_pose_code_.data(), pose_code_size());
  }
  for (size_t v = 0; v < videos_.size(); ++v) {
    const std::string video = "video" + std::to_string(v);
    fn(video + "/intrinsics", videos_[v].intrinsics.data(), 4);
    fn(video + "/appearance", videos_[v].appearance.data(), appearance_size());
    for (size_t t = 0; t < videos_[v].frames.size(); ++t) {
      FrameParameters& f = videos_[v].frames[t];
      const std::string frame = video + "/frame" + std::to_string(t);
      fn(frame + "/root_delta", f.root_delta.data(), kPoseSize);
      fn(frame + "/root_init", f.root_init.data(), kPoseSize);
      fn(frame + "/bones_t", f.bones_t.data(), static_cast<int>(f.bones_t.size()));
      if (delta_) fn(frame + "/pose_code", f.pose_code.data(), pose_code_size());
    }
  }
}

}  // namespace banmo
