// `banmo synth --realism casual`: what a handheld camera sees (docs/synth.md,
// "Realism"). The pieces here are pure functions of their inputs and of
// explicit random streams, so each effect can be tested on its own; the scene
// (scene.cc) composes them per frame.
//
// Seeding: every effect draws from its own stream, MixSeed(seed, kStream*,
// video[, frame]) (features.h), so switching one effect off or changing its
// parameters leaves the draws of the others unchanged.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "banmo/geometry/camera.h"
#include "banmo/util/enum_names.h"

namespace banmo::synth {

enum class Realism {
  kNone,    // today's renders: black background, exact masks, features, rough poses
  kCasual,  // handheld footage: see CasualOptions
};

}  // namespace banmo::synth

namespace banmo {
template <>
struct EnumNames<synth::Realism> {
  static constexpr std::pair<synth::Realism, const char*> kNames[] = {
      {synth::Realism::kNone, "none"}, {synth::Realism::kCasual, "casual"}};
};
}  // namespace banmo

namespace banmo::synth {

// Random streams of the casual effects (the `a` of MixSeed(seed, a, video,
// frame)); PlanScene and the plain renderer use 0 to 3.
inline constexpr std::uint64_t kStreamCasualVideo = 100;  // focal, light, exposure, WB, noise gain
inline constexpr std::uint64_t kStreamBackground = 101;   // the video's procedural world
inline constexpr std::uint64_t kStreamSensorNoise = 102;  // per frame
inline constexpr std::uint64_t kStreamMask = 103;         // per frame: boundary, holes, limb

struct CasualOptions {
  double focal_min = 0.6;  // focal length per video, uniform in [min, max] x image size
  double focal_max = 1.6;
  bool background = true;               // textured ground and backdrop; false: black
  bool shadow = true;                   // the object's shadow on the ground
  double shadow_strength = 0.75;        // fraction of the direct light the object blocks
  double ambient_min = 0.25;            // ambient fraction per video, uniform in [min, max]
  double ambient_max = 0.5;             //
  double light_elevation_min_deg = 25;  // sun elevation per video (azimuth uniform)
  double light_elevation_max_deg = 70;
  double exposure_min = 0.75;  // exposure gain per video, log-uniform in [min, max]
  double exposure_max = 1.3;
  double white_balance = 0.12;  // red and blue gains per video in [1 - wb, 1 + wb], green 1
  // Sensor noise, in 8-bit units before rounding: N(0, g^2 (read^2 + shot I))
  // per pixel and channel, I the noise-free value, g a per-video gain in
  // [noise_gain_min, noise_gain_max] (ISO).
  double noise_read = 1.5;
  double noise_shot = 0.25;
  double noise_gain_min = 0.6;
  double noise_gain_max = 1.4;
  int blur_subframes = 5;              // renders averaged per frame (1: no motion blur)
  double shutter = 0.5;                // exposure time as a fraction of the frame interval
  int jpeg_quality = 85;               // JPEG round trip of every frame (0: none)
  double mask_boundary_px = 2;         // largest displacement of the mask boundary
  double mask_boundary_smooth_px = 5;  // correlation length of the displacement
  int mask_holes_max = 3;              // 0 .. max holes per frame
  double mask_hole_radius_max_px = 2;  // hole radius in [0.7, max] px
  double limb_drop_rate = 0.05;        // probability that a frame's mask misses a limb
  double limb_share_min = 0.02;        // a limb: a node's subtree covering this share
  double limb_share_max = 0.3;         // of the object's pixels

  // Throws InputError naming the field and the expected range.
  void Check() const;
};

// What video `video` draws once (stream kStreamCasualVideo).
struct CasualVideo {
  double focal_factor = 1;                                 // fx = fy = focal_factor * image size
  Eigen::Vector3d light_world = Eigen::Vector3d::UnitY();  // unit, towards the sun, world y up
  double ambient = 0.35;
  double exposure = 1;
  Eigen::Vector3d white_balance = Eigen::Vector3d::Ones();  // R, G, B gains
  double noise_gain = 1;
};
CasualVideo DrawCasualVideo(const CasualOptions& options, std::uint64_t seed, int video);

// A video's procedural world (stream kStreamBackground): a ground plane at
// world height ground_y (under the object's lowest point) with a textured,
// cluttered floor, a cylinder backdrop of radius `radius` around the world
// origin with furniture-like clutter up to `height`, and sky above it.
struct BackgroundWorld {
  double ground_y = -1;
  double radius = 9;
  double height = 5;
  std::uint64_t seed = 0;
  Eigen::Vector3d floor_a, floor_b, floor_grain;  // floor colours (linear RGB in [0, 1])
  Eigen::Vector3d wall_a, wall_b;                 // backdrop colours
  Eigen::Vector3d sky_top, sky_horizon;
  double tile_size = 0;  // floor tiles (0: none)
  double clutter = 0.5;  // probability of an object per clutter cell
};
BackgroundWorld DrawBackgroundWorld(std::uint64_t seed, int video, double ground_y);

// Radiance (CV_32FC3, RGB, about [0, 1]) of the world seen by `camera` at
// camera_from_world, lit by the sun light_world with `ambient`; `shadow`
// (CV_32FC1 in [0, 1], or empty) removes shadow_strength x shadow of the
// direct light on the ground.
cv::Mat RenderBackground(const BackgroundWorld& world, const PinholeCamera& camera,
                         const Eigen::Isometry3d& camera_from_world,
                         const Eigen::Vector3d& light_world, double ambient,
                         const cv::Mat& shadow = cv::Mat(), double shadow_strength = 0);

// Vertices (world coordinates) flattened onto the ground plane y = ground_y
// along the light: x - ((x.y - ground_y) / l.y) l, l towards the light
// (l.y > 0). Rasterised through the camera they give the shadow.
Eigen::Matrix3Xd ProjectOntoGround(const Eigen::Matrix3Xd& world_vertices, double ground_y,
                                   const Eigen::Vector3d& light_world);

// Adds N(0, gain^2 (read^2 + shot max(I, 0))) to every channel of `image`
// (CV_32FC3, 8-bit units), in place, row by row from `rng`.
void AddSensorNoise(cv::Mat* image, double read, double shot, double gain, std::mt19937_64& rng);

// Encodes an RGB CV_8UC3 image as JPEG at `quality` (OpenCV / libjpeg) and
// decodes it again.
cv::Mat JpegRoundTrip(const cv::Mat& rgb, int quality);

// A segmenter-like mask from the exact one (CV_8UC1, 0 / 255):
//  1. boundary displaced by a smooth random field r (white noise filtered by
//     a Gaussian of sigma mask_boundary_smooth_px, divided by 1.5 times its
//     standard deviation, clamped to [-1, 1] and multiplied by an amplitude
//     drawn in [0.5, 1] x mask_boundary_px): a pixel is object iff sd + r > 0, sd the
//     signed distance of its centre to the boundary (+ inside, pixel centres
//     0.5 px from it), so only pixels within mask_boundary_px of the exact
//     boundary change;
//  2. 0 .. mask_holes_max holes, discs of radius [0.7, max] px centred on
//     object pixels at least 2 radii inside;
//  3. if `limb` is not empty (CV_8UC1, non-zero = the limb's pixels), those
//     pixels removed.
struct MaskDegradation {
  cv::Mat mask;
  std::vector<cv::Vec3f> holes;   // (x, y, radius) of each hole, pixel centres at +0.5
  int limb_pixels = 0;            // pixels removed by step 3
  double boundary_amplitude = 0;  // max |r| of step 1, px
};
MaskDegradation DegradeMask(const cv::Mat& exact, const cv::Mat& limb, const CasualOptions& options,
                            std::mt19937_64& rng);

}  // namespace banmo::synth
