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
//    world_from_root; the rough initialisation is G^t * R_noise with
//    R_noise a rotation by exactly pose_noise_deg about a seeded random axis
//    (independent per frame) through the root origin (the object centre).
//  - Videos are unsynchronised: video v plays the animation from a random
//    offset at a random speed in [1 - speed_jitter, 1 + speed_jitter].
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "banmo/geometry/camera.h"
#include "banmo/geometry/mesh.h"
#include "banmo/geometry/se3.h"
#include "banmo/io/dataset.h"
#include "banmo/synth/rasterizer.h"
#include "banmo/synth/rig.h"

namespace banmo::synth {

struct SynthOptions {
  int num_videos = 5;                         // V >= 1
  int frames_per_video = 60;                  // T >= 2
  int image_size = 256;                       // width = height in pixels, >= 16
  std::string animation;                      // animation name; empty: the rig's first
  double fps = 30;                            // frames per second of animation time
  std::vector<int> flow_gaps = {1, 2, 4, 8};  // positive, distinct; forward and backward flow
  double pose_noise_deg = 0;                  // rotation noise of the rough root poses, [0, 180]
  std::uint64_t seed = 0;                     // everything random derives from it
  double camera_distance = 3;                 // camera to object centre (the paper's ~3 units)
  double focal_factor = 1.0;                  // fx = fy = focal_factor * image_size (pixels)
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

// Camera and per-frame plan of every video (deterministic in options.seed).
struct ScenePlan {
  PinholeCamera camera;
  const Animation* animation = nullptr;  // points into the rig
  RigNormalization normalization;
  std::vector<std::vector<FramePlan>> frames;  // [video][frame]
};
ScenePlan PlanScene(const Rig& rig, const SynthOptions& options);

// Posed mesh of the rig at `time` in root coordinates (normalised).
Eigen::Matrix3Xd PosedVerticesInRoot(const Rig& rig, const ScenePlan& plan, double time);

struct SynthScene {
  Dataset dataset;
  std::vector<std::vector<TriangleMesh>> gt_meshes;  // [video][frame], camera coordinates
};

// Multiplies every length of `scene` by s > 0: root-pose translations (ground
// truth and rough), depth maps and ground-truth mesh vertices. With
// x_camera = R x_root + t, scaling x_root and t by s scales x_camera by s and
// leaves every projection unchanged. Used for SynthOptions::object_scale.
void ScaleScene(double s, SynthScene* scene);

// Renders the whole scene (both cores, frames in parallel). `progress`, if
// set, is called after each video with (videos done, total videos).
SynthScene RenderSyntheticScene(const Rig& rig, const SynthOptions& options,
                                const std::function<void(int, int)>& progress = {});

}  // namespace banmo::synth
