// The BANMo model's parameters: every Ceres parameter block lives here and
// persists across minibatches (docs/design.md).
//
// Blocks and their storage (all doubles):
//   sdf, color, embedding     MLP weights of the canonical fields (field/canonical_field.h)
//   log_beta (1)              log of VolSDF's Laplace scale
//   bones (kBoneSize B)       rest bones (deform/bones.h)
//   delta_skinning, rest_pose_code
//                             MLP_Delta weights and omega^* (deform/delta_skinning.h;
//                             only when options.delta_skinning.enabled)
//   appearance[v] (A)         per-video appearance code omega_e (Eq. 1)
//   per frame (video v, frame t):
//     root_delta (7)          dG^t, camera_from_root = G0^t * dG^t (Eq. 20,
//                             correction on the object side)
//     bones_t (kPoseSize B)   J_b^t posed_from_rest per bone (Eq. 8-10)
//     pose_code (P)           omega^t of delta skinning (when enabled)
//     intrinsics (4)          [fx, fy, cx, cy] of the video's camera (held
//                             constant unless a stage frees them)
//   G0^t (root_init) is data, not a parameter.
//
// Units: the model works in normalised units, dataset units divided by the
// scene scale s (scene_scale(); docs/solver.md, "Scene scale"), so that the
// canonical object is roughly unit-sized whatever the units of the data.
// Root translations (root_init, root_delta), canonical points, bones and
// every canonical-space length are in these units; projections do not
// depend on s (x_in_camera / s projects to the same pixel). Outputs
// (meshes, bones, glTF) are multiplied back by s.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "banmo/deform/bones.h"
#include "banmo/deform/delta_skinning.h"
#include "banmo/field/canonical_field.h"
#include "banmo/geometry/camera.h"
#include "banmo/geometry/se3.h"
#include "banmo/model/auto_size_options.h"
#include "banmo/model/parameter_group.h"
#include "banmo/model/root_registration_options.h"
#include "banmo/model/root_smoothing_options.h"
#include "banmo/volume/density_model.h"

namespace banmo {

struct ModelOptions {
  CanonicalFieldOptions field;    // MLP sizes, encoding, appearance code size
  int num_bones = 8;              // B; 0 = rigid object (no skinning)
  double init_bone_scale = 0.15;  // isotropic Gaussian scale of new bones (canonical units)
  double init_beta = 0.05;        // density scale beta at initialisation (canonical units)
  // How the SDF becomes rendering weights (volume/volume_rendering.h).
  DensityModel density = DensityModel::kVolSdf;
  uint32_t seed = 0;                    // MLP initialisation seed
  DeltaSkinningOptions delta_skinning;  // optional MLP_Delta (needs num_bones >= 1)
  // Scene scale s, dataset units per model unit (finite, > 0). Empty = auto:
  // estimated from the data by MakeModelForDataset (model/make_model.h).
  std::optional<double> scene_scale;
  // The canonical frame is the dataset's root frame translated so that its
  // origin is the object centre estimated from the masks and the rough root
  // poses (EstimateObjectCentre, model/scene_scale.h): the initial SDF
  // sphere, bones and canonical bounds start around the object wherever the
  // rig's origin is. false: the root frame as it is.
  bool recentre = true;
  AutoSizeOptions auto_size;  // automatic growth of B and the MLP widths
  // Temporal smoothing of the dataset's rough root poses before the model is
  // made from them (`banmo solve`; registration/root_init_smoothing.h).
  RootSmoothingOptions root_init_smoothing;
  // Registration of the frames from their pixel features when the dataset
  // has no root poses (`banmo solve`, before the smoothing;
  // registration/root_init_registration.h).
  RootRegistrationOptions root_init_registration;

  // Throws InputError naming the field on a violated constraint.
  void Check() const;
};

// The ray sampling the model was trained with (that of the last stage of its
// solver config): `banmo render` renders it the same way.
struct TrainingSampling {
  int samples_per_ray = 32;       // depth samples per ray (> 0)
  double near_far_margin = 0.2;   // near/far planes widened by this fraction (>= 0)
  bool importance_depth = false;  // second pass of samples around the surface
  bool clip_to_box = false;       // rays clipped to the widened canonical bounds
  double clip_margin = 0.1;       // their widening, fraction of the largest side (>= 0)
  int importance_samples = 0;     // SamplingConfig::importance_samples (>= 0)
  bool min_sdf_sample = false;    // SamplingConfig::min_sdf_sample
};

struct FrameParameters {
  Pose root_delta = PoseIdentity();  // dG^t (translation in model units)
  Pose root_init = PoseIdentity();   // G0^t (data; translation in model units)
  std::vector<double> bones_t;       // kPoseSize * B
  std::vector<double> pose_code;     // omega^t (P; empty without delta skinning)
};

struct VideoParameters {
  PinholeCamera camera;
  Eigen::Vector4d intrinsics = Eigen::Vector4d(1, 1, 0, 0);  // parameter block
  std::vector<double> appearance;                            // A
  std::vector<FrameParameters> frames;
};

class Model {
 public:
  // frames_per_video[v] frames in video v. Bones start on a small sphere
  // inside the initial SDF sphere; bone transforms at the identity. The
  // scene scale is options.scene_scale, or 1 when that is auto.
  Model(const ModelOptions& options, const std::vector<int>& frames_per_video,
        const std::vector<PinholeCamera>& cameras);

  const ModelOptions& options() const { return options_; }
  const CanonicalField& field() const { return *field_; }
  // Coarse-to-fine annealing of the field's position encoding
  // (PositionalEncoding::SetAnnealing); not a parameter, not saved.
  void SetFieldAnnealing(double alpha) { field_->SetAnnealing(alpha); }
  // The density model from now on (schedule.neus_from switches to NeuS
  // part-way; the model file records the current one).
  void SetDensity(DensityModel density) { options_.density = density; }
  int num_bones() const { return options_.num_bones; }
  int num_videos() const { return static_cast<int>(videos_.size()); }
  // Scene scale s: a length of the model times s is in dataset units.
  double scene_scale() const { return scene_scale_; }
  // Sets s (finite, > 0). Converts nothing: set it before the root poses are
  // filled in (MakeModelForDataset) or when loading a checkpoint.
  void set_scene_scale(double s);

  // The canonical box the solver sampled in (near/far planes, eikonal points,
  // soft-argmax grid; canonical model units) when the model was saved; empty
  // when not recorded (models saved before it was stored, or never trained).
  const std::optional<Eigen::AlignedBox3d>& canonical_bounds() const { return canonical_bounds_; }
  void set_canonical_bounds(const Eigen::AlignedBox3d& bounds) { canonical_bounds_ = bounds; }
  // The ray sampling of training; empty when not recorded.
  const std::optional<TrainingSampling>& training_sampling() const { return training_sampling_; }
  void set_training_sampling(const TrainingSampling& s) { training_sampling_ = s; }
  // Where the canonical origin is in the dataset's root frame (model units):
  // G0^t = camera_from_root^t * T(canonical_origin) (MakeModelForDataset).
  // Zero for models made with recentre off or saved before it was recorded.
  const Eigen::Vector3d& canonical_origin() const { return canonical_origin_; }
  void set_canonical_origin(const Eigen::Vector3d& c) { canonical_origin_ = c; }

  double* sdf() { return sdf_.data(); }
  double* color() { return color_.data(); }
  double* embedding() { return embedding_.data(); }
  double* log_beta() { return &log_beta_; }
  double* bones() { return bones_.data(); }
  const double* sdf() const { return sdf_.data(); }
  const double* color() const { return color_.data(); }
  const double* embedding() const { return embedding_.data(); }
  const double* log_beta() const { return &log_beta_; }
  const double* bones() const { return bones_.data(); }
  // Delta skinning (null / empty when the model has none).
  const DeltaSkinning* delta_skinning() const { return delta_.get(); }
  bool has_delta_skinning() const { return delta_ != nullptr; }
  double* delta_skinning_params() { return delta_params_.data(); }
  const double* delta_skinning_params() const { return delta_params_.data(); }
  int delta_skinning_size() const { return static_cast<int>(delta_params_.size()); }
  double* rest_pose_code() { return rest_pose_code_.data(); }
  const double* rest_pose_code() const { return rest_pose_code_.data(); }
  int pose_code_size() const { return static_cast<int>(rest_pose_code_.size()); }
  // Whether delta skinning changes any warp: the model has it and its output
  // layer is not all zeros (DeltaSkinning::IsZero).
  bool DeltaSkinningIsNonZero() const;
  int sdf_size() const { return static_cast<int>(sdf_.size()); }
  int color_size() const { return static_cast<int>(color_.size()); }
  int embedding_size() const { return static_cast<int>(embedding_.size()); }
  int bones_size() const { return static_cast<int>(bones_.size()); }
  int appearance_size() const { return options_.field.appearance_code_dim; }

  VideoParameters& video(int v) { return videos_[v]; }
  const VideoParameters& video(int v) const { return videos_[v]; }
  FrameParameters& frame(int v, int t) { return videos_[v].frames[t]; }
  const FrameParameters& frame(int v, int t) const { return videos_[v].frames[t]; }

  // camera_from_root G^t = dG^t * G0^t.
  Pose RootPose(int v, int t) const;

  // Visits every block (parameters and the G0^t data) in a fixed order:
  // sdf, color, embedding, log_beta, bones, [delta_skinning, rest_pose_code],
  // then per video: intrinsics, appearance, and per frame: root_delta,
  // root_init, bones_t, [pose_code] ([..] only with delta skinning). Names
  // are e.g. "sdf", "video3/intrinsics", "video3/frame12/root_delta".
  void ForEachBlock(const std::function<void(const std::string& name, double* data, int size)>& fn);
  // The same blocks, read only.
  void ForEachBlock(
      const std::function<void(const std::string& name, const double* data, int size)>& fn) const;
  // The parameter group of the block ForEachBlock names `name` (its last
  // path component: "video3/frame12/root_delta" is kRoot; delta_skinning
  // and rest_pose_code are kDeltaSkinning); none for root_init (data, not
  // a parameter) or a name no block has.
  static std::optional<ParameterGroup> BlockGroup(const std::string& name);

  // Size changes (automatic model sizing, optim/auto_size.h). Both move
  // the blocks they touch (any ceres::Problem holding them must drop them
  // first) and keep options() in step.
  //
  // B becomes num_bones: the rest bones take `bones` (kBoneSize num_bones
  // values), every frame's bones_t keeps its first min(B, num_bones)
  // transforms and gets identities after them. Not with delta skinning
  // (MLP_Delta's output size is B).
  void SetBones(int num_bones, const std::vector<double>& bones);
  // New SDF / colour MLP widths with their parameters (sizes of the new
  // field's blocks). The position encoding keeps its annealing state.
  void SetFieldWidths(int sdf_width, int color_width, std::vector<double> sdf,
                      std::vector<double> color);

 private:
  ModelOptions options_;
  std::unique_ptr<CanonicalField> field_;
  std::unique_ptr<DeltaSkinning> delta_;
  std::vector<double> sdf_, color_, embedding_, bones_;
  std::vector<double> delta_params_, rest_pose_code_;
  double log_beta_ = 0.0;
  double scene_scale_ = 1.0;
  std::optional<Eigen::AlignedBox3d> canonical_bounds_;
  std::optional<TrainingSampling> training_sampling_;
  Eigen::Vector3d canonical_origin_ = Eigen::Vector3d::Zero();
  std::vector<VideoParameters> videos_;

  // ForEachBlock of both constnesses (Self = Model or const Model).
  template <class Self, class Fn>
  static void VisitBlocks(Self& self, const Fn& fn);
};

}  // namespace banmo
