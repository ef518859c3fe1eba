// Synthetic multi-video scenes: a rig, posed by its animation, rendered along
// several camera trajectories (the paper's "Animated Objects" protocol).
//
// Frames (see docs/synth.md for the full description):
//  - Root frame: the rest mesh normalised so that its axis-aligned bounding
//    box is centred at the origin with largest half-extent 1:
//    x_root = scale * (x_rig - center). Posed meshes are expressed in the same
//    root frame (articulation incl. any root motion of the animation).
//  - world_from_root(t): a slow yaw wobble and a small horizontal drift.
//  - camera_from_world(t): a look-at camera on an orbit arc around the posed
//    object's centre, at `camera_distance`, with its own azimuth range and
//    elevation per video (consecutive videos share `azimuth_overlap` of their
//    sweep), OpenCV axes (x right, y down, z forward), world y up.
//  - Ground truth root pose G^t = camera_from_root = camera_from_world *
//    world_from_root; the rough initialisation is G^t * R_noise, R_noise a
//    rotation through the root origin (the object centre) drawn per frame by
//    the pose-noise model (PoseNoiseModel below): by exactly pose_noise_deg
//    about a seeded random axis (`exact`, the default), or a Gaussian rotation
//    vector whose mean angle is pose_noise_deg with the translation reset to
//    (0, 0, camera_distance) (`gaussian`, BANMo's ablation).
//  - Videos are unsynchronised: video v plays the animation from a random
//    offset at a random speed in [1 - speed_jitter, 1 + speed_jitter].
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "banmo/geometry/camera.h"
#include "banmo/geometry/mesh.h"
#include "banmo/geometry/se3.h"
#include "banmo/io/dataset.h"
#include "banmo/synth/rasterizer.h"
#include "banmo/synth/realism.h"
#include "banmo/synth/rig.h"
#include "banmo/util/enum_names.h"

namespace banmo::synth {

// How the rough root poses are drawn from the ground truth (docs/synth.md,
// "Pose noise"). Both rotate about the root origin (the object centre), both
// independently per frame from a stream seeded by SynthOptions::seed.
enum class PoseNoiseModel {
  // Rotation by exactly pose_noise_deg about a uniformly random axis; the
  // translation is the ground truth's.
  kExact,
  // BANMo's ablation (scripts/misc/add_cam_noise.py): rotation vector
  // w ~ N(0, sigma^2 I_3), sigma = GaussianNoiseSigma(pose_noise_deg) so that
  // the mean rotation angle is pose_noise_deg; the translation is reset to
  // (0, 0, camera_distance) (the script's (0, 0, 3)), i.e. the object centre
  // is put on the optical axis at the nominal distance.
  kGaussian,
};

}  // namespace banmo::synth

namespace banmo {
template <>
struct EnumNames<synth::PoseNoiseModel> {
  static constexpr std::pair<synth::PoseNoiseModel, const char*> kNames[] = {
      {synth::PoseNoiseModel::kExact, "exact"}, {synth::PoseNoiseModel::kGaussian, "gaussian"}};
};
}  // namespace banmo

namespace banmo::synth {

// The Gaussian model's mean rotation angle E[angle(exp([w]))] in radians, for
// w ~ N(0, sigma^2 I_3) (sigma in radians). |w| is Maxwell distributed; the
// rotation angle is |w| folded into [0, pi] (2 pi periodic, mirrored), so the
// mean is sigma * 2 sqrt(2 / pi) for small sigma, peaks at
// kGaussianNoisePeak.mean_angle and then falls towards pi / 2 (large sigma:
// the folded angle becomes uniform in [0, pi]). Evaluated in closed form, the
// Maxwell distribution function and partial first moment on each fold
// interval [k pi, (k + 1) pi] (erf and exp only; relative error ~1e-15).
double GaussianNoiseMeanAngle(double sigma);

// The largest mean angle of the Gaussian model and the sigma where it is
// reached (radians), found once by golden-section search on [0.5, 3] rad:
// mean 122.556 deg at sigma ~99.2 deg. The mean is flat at its peak, so the
// sigma is known to ~1e-7 rad only, the mean to ~1e-15 rad.
struct GaussianNoisePeak {
  double sigma = 0;
  double mean_angle = 0;
};
GaussianNoisePeak GaussianNoiseMaximum();

// The per-axis sigma (radians) whose mean rotation angle is `mean_angle`
// (radians): the smallest such sigma, by bisection on [0, peak sigma] (the
// mean is increasing there) to 1e-14 rad, so the mean is matched to ~1e-14
// rad. Mean 20 / 50 / 90 deg: sigma 12.533 / 31.333 / 56.804 deg. Throws
// InputError if mean_angle is outside [0, peak mean angle].
double GaussianNoiseSigma(double mean_angle);

// One draw of the rotation R_noise of the rough pose (G_init = G_gt * R_noise)
// for `model`: `exact` rotates by angle (radians) about a random unit axis (3
// normal draws, redrawn if their norm is below 1e-6); `gaussian` uses
// sigma (radians) * (3 normal draws) as the rotation vector. `angle` is used
// by `exact`, `sigma` by `gaussian`.
Eigen::Matrix3d DrawPoseNoiseRotation(PoseNoiseModel model, double angle, double sigma,
                                      std::mt19937_64& rng);

struct SynthOptions {
  int num_videos = 5;                         // V >= 1
  int frames_per_video = 60;                  // T >= 2
  int image_size = 256;                       // width = height in pixels, >= 16
  std::string animation;                      // animation name; empty: the rig's first
  double fps = 30;                            // frames per second of animation time
  std::vector<int> flow_gaps = {1, 2, 4, 8};  // positive, distinct; forward and backward flow
  double pose_noise_deg = 0;                  // rotation noise of the rough root poses, [0, 180]
  // exact: every frame is off by pose_noise_deg; gaussian: the mean over
  // frames is pose_noise_deg (at most 122.55), and the translation is reset.
  PoseNoiseModel pose_noise_model = PoseNoiseModel::kExact;
  std::uint64_t seed = 0;         // everything random derives from it
  double camera_distance = 3;     // camera to object centre (the paper's ~3 units)
  double focal_factor = 1.0;      // fx = fy = focal_factor * image_size (pixels)
  double azimuth_overlap = 0.5;   // fraction of a video's sweep shared with the next, [0, 1)
  double elevation_min_deg = -5;  // camera elevation range over the videos
  double elevation_max_deg = 40;
  double elevation_wobble_deg = 8;    // elevation oscillation within a video
  double root_yaw_wobble_deg = 20;    // world_from_root yaw oscillation amplitude
  double root_drift = 0.2;            // world_from_root translation amplitude (root units)
  double speed_jitter = 0.15;         // animation speed in [1 - j, 1 + j] per video, [0, 1)
  double feature_noise = 0.05;        // std of the per-channel feature noise, >= 0
  double occlusion_tolerance = 0.01;  // relative depth tolerance of the flow visibility test
  double ambient = 0.35;              // ambient light fraction in [0, 1]; the rest is Lambert
  Eigen::Vector3d light_in_camera = Eigen::Vector3d(-0.3, -0.5, -1.0);  // towards the light
  Eigen::Vector3i background = Eigen::Vector3i(0, 0, 0);  // RGB of the background, [0, 255]
  // Object scale s in [1e-6, 1e6]: the whole scene (root frame, camera
  // distance, root-pose translations, depth, ground-truth meshes) is scaled by
  // s after rendering, so images, masks, flow and features are unchanged and
  // only lengths differ (the stability suite's tiny and huge objects).
  double object_scale = 1.0;
  // Where the object's rest bounding-box centre sits in the root frame
  // (normalised root units, before object_scale): the written root poses
  // become camera_from_root * T(-root_offset), nothing else changes (images,
  // flow, features, ground-truth meshes and the noise of the rough poses
  // are those of the centred scene). Models rigs whose origin is far from
  // the object, as glTF rigs with the origin at the feet. |.| <= 100.
  Eigen::Vector3d root_offset = Eigen::Vector3d::Zero();
  // none: the renders above. casual: what a handheld camera sees (realism.h,
  // docs/synth.md "Realism"): per-video focal length (the dataset gets the
  // default assumption, the truth as intrinsics_gt) with the camera distance
  // scaled by it, a textured world with the object's shadow, per-video light,
  // exposure and white balance, motion blur, sensor noise, JPEG, degraded
  // masks (exact ones in mask_gt), no features, and rough root poses that are
  // all the identity at (0, 0, camera_distance) (the truth stays in
  // root_poses_gt). pose_noise_deg must be 0.
  Realism realism = Realism::kNone;
  CasualOptions casual;

  // Throws InputError naming the offending field and the expected range.
  void Check() const;
};

// x_root = scale * (x_rig - center): the rest mesh's bounding box centred at
// the origin with largest half-extent 1.
struct RigNormalization {
  double scale = 1;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
};
RigNormalization ComputeNormalization(const Rig& rig);

// Everything decided for one frame before rendering.
struct FramePlan {
  double animation_time = 0;  // seconds, already wrapped into the clip
  Pose camera_from_root_gt = PoseIdentity();
  Pose camera_from_root_init = PoseIdentity();
};

// How video v's camera and object move, drawn once per video.
struct VideoPath {
  double azimuth0_deg = 0;   // start of the orbit arc
  double sweep_deg = 0;      // arc swept over the video
  double distance = 3;       // camera to the posed object's centre
  double speed = 1;          // animation speed
  double offset = 0;         // animation time offset (seconds)
  double yaw0_deg = 0;       // world_from_root yaw
  double phase = 0;          // of the wobbles (radians)
  double elevation_deg = 0;  // mean camera elevation
};

// Camera and object at a (possibly fractional) frame of a video.
struct FrameCameras {
  double animation_time = 0;
  Eigen::Isometry3d world_from_root = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d camera_from_world = Eigen::Isometry3d::Identity();
};

// Camera and per-frame plan of every video (deterministic in options.seed).
struct ScenePlan {
  PinholeCamera camera;                  // the nominal camera (focal_factor)
  std::vector<PinholeCamera> cameras;    // per video: `camera`, or the casual focal length
  std::vector<VideoPath> paths;          // per video
  std::vector<CasualVideo> casual;       // per video, realism casual only
  const Animation* animation = nullptr;  // points into the rig
  RigNormalization normalization;
  std::vector<std::vector<FramePlan>> frames;  // [video][frame]
};
ScenePlan PlanScene(const Rig& rig, const SynthOptions& options);

// Where object and camera of video `video` are at frame `frame` (fractional
// frames lie between the planned ones: motion blur). At whole frames
// camera_from_world * world_from_root is the plan's camera_from_root_gt.
FrameCameras CamerasAt(const Rig& rig, const ScenePlan& plan, const SynthOptions& options,
                       int video, double frame);

// Posed mesh of the rig at `time` in root coordinates (normalised).
Eigen::Matrix3Xd PosedVerticesInRoot(const Rig& rig, const ScenePlan& plan, double time);

// What realism casual did to one frame (for summaries and tests).
struct CasualFrameRecord {
  int limb_node = -1;             // rig node whose subtree's pixels the mask misses, -1: none
  int limb_pixels = 0;            // object pixels removed with it
  int holes = 0;                  // holes punched into the mask
  double boundary_amplitude = 0;  // largest boundary displacement, px
};

struct SynthScene {
  Dataset dataset;
  std::vector<std::vector<TriangleMesh>> gt_meshes;    // [video][frame], camera coordinates
  std::vector<std::vector<CasualFrameRecord>> casual;  // [video][frame], realism casual only
};

// Multiplies every length of `scene` by s > 0: root-pose translations (ground
// truth and rough), depth maps and ground-truth mesh vertices. With
// x_camera = R x_root + t, scaling x_root and t by s scales x_camera by s and
// leaves every projection unchanged. Used for SynthOptions::object_scale.
void ScaleScene(double s, SynthScene* scene);

// Error of the rough root poses against the ground truth over the frames of
// video `video` (-1: all videos) that have a ground-truth pose. Rotation: the
// geodesic angle between the rotations, degrees; translation: |t_init -
// t_gt| in scene units. p90 is the nearest-rank 90th percentile (the
// ceil(0.9 n)-th smallest value).
struct PoseNoiseStats {
  int frames = 0;
  double rotation_mean_deg = 0;
  double rotation_p90_deg = 0;
  double rotation_max_deg = 0;
  double translation_mean = 0;
  double translation_p90 = 0;
};
PoseNoiseStats MeasurePoseNoise(const Dataset& dataset, int video = -1);

// The noise model of `options` in words, e.g. "gaussian, mean 50 deg
// (per-axis sigma 31.34 deg), translation reset to (0, 0, 3)" or "exact, 20
// deg about a random axis, translation kept". Checks the options first.
std::string DescribePoseNoise(const SynthOptions& options);

// Renders the whole scene (both cores, frames in parallel). `progress`, if
// set, is called after each video with (videos done, total videos). When the
// rough poses are not the ground truth (pose_noise_deg > 0 or the gaussian
// model), each video's root_poses_init_comment records the noise model and
// the measured error of that video and of the whole dataset.
SynthScene RenderSyntheticScene(const Rig& rig, const SynthOptions& options,
                                const std::function<void(int, int)>& progress = {});

}  // namespace banmo::synth
