#include "banmo/synth/scene.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "banmo/synth/features.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo::synth {

void SynthOptions::Check() const {
  auto fail = [](const char* field, const std::string& expected) {
    ThrowInputError("synth option ", field, ": expected ", expected);
  };
  if (num_videos < 1) fail("num_videos", ">= 1");
  if (frames_per_video < 2) fail("frames_per_video", ">= 2");
  if (image_size < 16 || image_size > 8192) fail("image_size", "in [16, 8192]");
  if (!(fps > 0) || !std::isfinite(fps)) fail("fps", "> 0");
  std::set<int> gaps;
  for (int g : flow_gaps) {
    if (g < 1) fail("flow_gaps", "positive gaps");
    if (!gaps.insert(g).second) fail("flow_gaps", "distinct gaps");
  }
  if (!(pose_noise_deg >= 0 && pose_noise_deg <= 180)) fail("pose_noise_deg", "in [0, 180]");
  if (pose_noise_model == PoseNoiseModel::kGaussian) {
    const double max_deg = GaussianNoiseMaximum().mean_angle * 180 / M_PI;
    if (!(pose_noise_deg <= max_deg)) {
      std::ostringstream expected;
      expected << "at most " << std::floor(max_deg * 100) / 100
               << " with the gaussian model (the largest mean rotation angle a Gaussian rotation "
                  "vector reaches); use the exact model for larger errors";
      fail("pose_noise_deg", expected.str());
    }
  }
  if (!(camera_distance > 1.5) || !std::isfinite(camera_distance)) {
    fail("camera_distance", "> 1.5 (the object has half-extent 1)");
  }
  if (!(focal_factor > 0) || !std::isfinite(focal_factor)) fail("focal_factor", "> 0");
  if (!(azimuth_overlap >= 0 && azimuth_overlap < 1)) fail("azimuth_overlap", "in [0, 1)");
  if (!(elevation_min_deg >= -80 && elevation_max_deg <= 80 &&
        elevation_min_deg <= elevation_max_deg)) {
    fail("elevation_min_deg/elevation_max_deg", "-80 <= min <= max <= 80");
  }
  if (!(std::abs(elevation_wobble_deg) <= 10)) fail("elevation_wobble_deg", "|.| <= 10");
  if (!(object_scale >= 1e-6 && object_scale <= 1e6)) fail("object_scale", "in [1e-6, 1e6]");
  if (!(root_offset.allFinite() && root_offset.norm() <= 100)) {
    fail("root_offset", "finite with length <= 100");
  }
  if (!std::isfinite(root_yaw_wobble_deg)) fail("root_yaw_wobble_deg", "a finite number");
  if (!(root_drift >= 0 && root_drift <= 1)) fail("root_drift", "in [0, 1]");
  if (!(speed_jitter >= 0 && speed_jitter < 1)) fail("speed_jitter", "in [0, 1)");
  if (!(feature_noise >= 0 && feature_noise < 10)) fail("feature_noise", "in [0, 10)");
  if (!(occlusion_tolerance >= 0 && occlusion_tolerance < 0.5)) {
    fail("occlusion_tolerance", "in [0, 0.5)");
  }
  if (!(ambient >= 0 && ambient <= 1)) fail("ambient", "in [0, 1]");
  if (!(light_in_camera.norm() > 0) || !light_in_camera.allFinite()) {
    fail("light_in_camera", "a non-zero direction");
  }
  if (background.minCoeff() < 0 || background.maxCoeff() > 255) fail("background", "in [0, 255]");
  if (realism == Realism::kCasual) {
    casual.Check();
    if (pose_noise_deg != 0 || pose_noise_model != PoseNoiseModel::kExact) {
      fail("pose_noise_deg",
           "0 with the exact model under realism casual (it writes no rough "
           "root poses: every root_poses_init is the identity)");
    }
  }
}

RigNormalization ComputeNormalization(const Rig& rig) {
  const Eigen::Vector3d lo = rig.rest_vertices.rowwise().minCoeff();
  const Eigen::Vector3d hi = rig.rest_vertices.rowwise().maxCoeff();
  RigNormalization n;
  n.center = 0.5 * (lo + hi);
  const double half = 0.5 * (hi - lo).maxCoeff();
  CHECK_GT(half, 0) << "degenerate rest mesh";
  n.scale = 1.0 / half;
  return n;
}

Eigen::Matrix3Xd PosedVerticesInRoot(const Rig& rig, const ScenePlan& plan, double time) {
  Eigen::Matrix3Xd x = PoseRig(rig, plan.animation, time);
  x.colwise() -= plan.normalization.center;
  return plan.normalization.scale * x;
}

namespace {

constexpr double kDegToRad = M_PI / 180;

// OpenCV-axes look-at: z towards the target, y down (world y is up).
Eigen::Isometry3d CameraFromWorldLookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitY());
  if (x.norm() < 1e-9) x = Eigen::Vector3d::UnitX();  // looking straight up/down
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d world_from_camera_rot;
  world_from_camera_rot << x, y, z;
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  world_from_camera.linear() = world_from_camera_rot;
  world_from_camera.translation() = eye;
  return world_from_camera.inverse();
}

Eigen::Vector3d RandomUnitVector(std::mt19937_64& rng) {
  Eigen::Vector3d v;
  do {
    v = Eigen::Vector3d(NormalDraw(rng), NormalDraw(rng), NormalDraw(rng));
  } while (v.norm() < 1e-6);
  return v.normalized();
}

}  // namespace

double GaussianNoiseMeanAngle(double sigma) {
  CHECK(sigma >= 0 && std::isfinite(sigma)) << "sigma " << sigma;
  if (sigma == 0) return 0;
  // Maxwell density f(r) = sqrt(2/pi) r^2 / sigma^3 exp(-r^2 / (2 sigma^2));
  // with u = x^2 / (2 sigma^2):
  //   F(x)  = int_0^x f       = erf(x / (sigma sqrt 2)) - sqrt(2/pi) (x/sigma) e^-u
  //   M1(x) = int_0^x r f(r)  = 2 sigma sqrt(2/pi) (1 - (1 + u) e^-u)
  // The angle is r - k pi on [k pi, (k+1) pi] for even k, (k+1) pi - r for odd k.
  const double c = std::sqrt(2 / M_PI);
  auto cdf = [&](double x) {
    return std::erf(x / (sigma * M_SQRT2)) -
           c * (x / sigma) * std::exp(-x * x / (2 * sigma * sigma));
  };
  auto moment = [&](double x) {
    const double u = x * x / (2 * sigma * sigma);
    return 2 * sigma * c * (1 - (1 + u) * std::exp(-u));
  };
  double mean = 0;
  double f_lo = 0, m_lo = 0;
  // Beyond 40 sigma the Maxwell tail is below e^-800: nothing left to add.
  for (int k = 0; k * M_PI < 40 * sigma; ++k) {
    const double f_hi = cdf((k + 1) * M_PI), m_hi = moment((k + 1) * M_PI);
    if (k % 2 == 0) {
      mean += (m_hi - m_lo) - k * M_PI * (f_hi - f_lo);
    } else {
      mean += (k + 1) * M_PI * (f_hi - f_lo) - (m_hi - m_lo);
    }
    f_lo = f_hi;
    m_lo = m_hi;
  }
  return mean;
}

GaussianNoisePeak GaussianNoiseMaximum() {
  static const GaussianNoisePeak peak = [] {
    // Golden-section search for the maximum on [0.5, 3] rad (the mean rises
    // up to ~1.75 rad and falls after it; docs/synth.md has the curve).
    const double g = (std::sqrt(5.0) - 1) / 2;
    double a = 0.5, b = 3.0;
    double x1 = b - g * (b - a), x2 = a + g * (b - a);
    double f1 = GaussianNoiseMeanAngle(x1), f2 = GaussianNoiseMeanAngle(x2);
    while (b - a > 1e-12) {
      if (f1 < f2) {
        a = x1;
        x1 = x2;
        f1 = f2;
        x2 = a + g * (b - a);
        f2 = GaussianNoiseMeanAngle(x2);
      } else {
        b = x2;
        x2 = x1;
        f2 = f1;
        x1 = b - g * (b - a);
        f1 = GaussianNoiseMeanAngle(x1);
      }
    }
    GaussianNoisePeak p;
    p.sigma = 0.5 * (a + b);
    p.mean_angle = GaussianNoiseMeanAngle(p.sigma);
    return p;
  }();
  return peak;
}

double GaussianNoiseSigma(double mean_angle) {
  const GaussianNoisePeak peak = GaussianNoiseMaximum();
  if (!(mean_angle >= 0 && mean_angle <= peak.mean_angle)) {
    ThrowInputError("gaussian pose noise: a mean rotation angle of ", mean_angle * 180 / M_PI,
                    " deg is not reachable (expected 0 to ", peak.mean_angle * 180 / M_PI,
                    " deg, reached at per-axis sigma ", peak.sigma * 180 / M_PI, " deg)");
  }
  if (mean_angle == 0) return 0;
  // The mean is increasing on [0, peak.sigma]: bisection for the crossing.
  double lo = 0, hi = peak.sigma;
  while (hi - lo > 1e-14) {
    const double mid = 0.5 * (lo + hi);
    if (GaussianNoiseMeanAngle(mid) < mean_angle) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return 0.5 * (lo + hi);
}

Eigen::Matrix3d DrawPoseNoiseRotation(PoseNoiseModel model, double angle, double sigma,
                                      std::mt19937_64& rng) {
  if (model == PoseNoiseModel::kExact) {
    const Eigen::Vector3d axis = RandomUnitVector(rng);
    return Eigen::AngleAxisd(angle, axis).toRotationMatrix();
  }
  const double x = NormalDraw(rng), y = NormalDraw(rng), z = NormalDraw(rng);
  const Eigen::Vector3d w = sigma * Eigen::Vector3d(x, y, z);
  const double norm = w.norm();
  if (norm == 0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(norm, w / norm).toRotationMatrix();
}

ScenePlan PlanScene(const Rig& rig, const SynthOptions& options) {
  options.Check();
  const std::string problem = rig.Validate();
  if (!problem.empty()) ThrowInputError("rig '", rig.name, "': ", problem);
  ScenePlan plan;
  if (options.animation.empty()) {
    if (rig.animations.empty()) ThrowInputError("rig '", rig.name, "' has no animation");
    plan.animation = &rig.animations[0];
  } else {
    const int a = rig.FindAnimation(options.animation);
    if (a < 0) {
      std::ostringstream names;
      for (const auto& anim : rig.animations)
        names << (names.tellp() > 0 ? ", " : "") << "'" << anim.name << "'";
      ThrowInputError("rig '", rig.name, "' has no animation '", options.animation,
                      "' (it has: ", names.str().empty() ? "none" : names.str(), ")");
    }
    plan.animation = &rig.animations[a];
  }
  plan.normalization = ComputeNormalization(rig);
  const int s = options.image_size;
  plan.camera.width = plan.camera.height = s;
  plan.camera.intrinsics =
      Eigen::Vector4d(options.focal_factor * s, options.focal_factor * s, 0.5 * s, 0.5 * s);

  const int nvid = options.num_videos, nfr = options.frames_per_video;
  // Elevations evenly spread over the range, shuffled (seeded).
  std::mt19937_64 scene_rng(MixSeed(options.seed, 0));
  std::vector<double> elevation(nvid);
  for (int v = 0; v < nvid; ++v) {
    const double a = nvid == 1 ? 0.5 : static_cast<double>(v) / (nvid - 1);
    elevation[v] =
        options.elevation_min_deg + a * (options.elevation_max_deg - options.elevation_min_deg);
  }
  for (int v = nvid - 1; v > 0; --v) {
    const int j = std::min(v, static_cast<int>(UniformDraw(scene_rng) * (v + 1)));
    std::swap(elevation[v], elevation[j]);
  }
  // Azimuth: video v starts at v * 360 / V (+ jitter) and sweeps so that
  // consecutive videos share `azimuth_overlap` of their arc.
  const double spacing = 360.0 / nvid;
  const double sweep = nvid == 1 ? 180.0 : std::min(360.0, spacing / (1 - options.azimuth_overlap));
  const double duration = plan.animation->Duration();
  const double noise_angle = options.pose_noise_deg * kDegToRad;
  const double noise_sigma =
      options.pose_noise_model == PoseNoiseModel::kGaussian ? GaussianNoiseSigma(noise_angle) : 0.0;

  plan.frames.resize(nvid);
  plan.cameras.assign(nvid, plan.camera);
  plan.paths.resize(nvid);
  if (options.realism == Realism::kCasual) {
    for (int v = 0; v < nvid; ++v) {
      plan.casual.push_back(DrawCasualVideo(options.casual, options.seed, v));
      const double f = plan.casual[v].focal_factor * s;
      plan.cameras[v].intrinsics = Eigen::Vector4d(f, f, 0.5 * s, 0.5 * s);
    }
  }
  for (int v = 0; v < nvid; ++v) {
    std::mt19937_64 rng(MixSeed(options.seed, 1, v));
    VideoPath& path = plan.paths[v];
    path.azimuth0_deg = v * spacing + (UniformDraw(rng) - 0.5) * 0.2 * spacing;
    path.sweep_deg = sweep;
    path.distance = options.camera_distance * (1 + 0.1 * (UniformDraw(rng) - 0.5));
    // A longer lens from further away: the object keeps its size in the image.
    if (options.realism == Realism::kCasual) {
      path.distance *= plan.casual[v].focal_factor / options.focal_factor;
    }
    path.speed = 1 + options.speed_jitter * (2 * UniformDraw(rng) - 1);
    path.offset = UniformDraw(rng) * std::max(duration, 1e-9);
    path.yaw0_deg = 360 * UniformDraw(rng);
    path.phase = 2 * M_PI * UniformDraw(rng);
    path.elevation_deg = elevation[v];
    std::mt19937_64 noise_rng(MixSeed(options.seed, 2, v));
    plan.frames[v].resize(nfr);
    for (int f = 0; f < nfr; ++f) {
      FramePlan& fp = plan.frames[v][f];
      const FrameCameras cams = CamerasAt(rig, plan, options, v, f);
      fp.animation_time = cams.animation_time;
      const Eigen::Isometry3d camera_from_root = cams.camera_from_world * cams.world_from_root;
      fp.camera_from_root_gt = PoseFromIsometry(camera_from_root);
      // Rough initialisation: a rotation about the root origin.
      Eigen::Isometry3d noise = Eigen::Isometry3d::Identity();
      noise.linear() =
          DrawPoseNoiseRotation(options.pose_noise_model, noise_angle, noise_sigma, noise_rng);
      Eigen::Isometry3d init = camera_from_root * noise;
      // BANMo's ablation: the object centre on the optical axis at the
      // nominal distance (the script's t = (0, 0, 3)).
      if (options.pose_noise_model == PoseNoiseModel::kGaussian) {
        init.translation() = Eigen::Vector3d(0, 0, options.camera_distance);
      }
      fp.camera_from_root_init = PoseFromIsometry(init);
    }
  }
  return plan;
}

FrameCameras CamerasAt(const Rig& rig, const ScenePlan& plan, const SynthOptions& options,
                       int video, double frame) {
  const VideoPath& path = plan.paths[video];
  const int nfr = options.frames_per_video;
  const double a = frame / (nfr - 1);  // progress in [0, 1]
  FrameCameras out;
  out.animation_time = plan.animation->WrapTime(plan.animation->StartTime() + path.offset +
                                                path.speed * frame / options.fps);
  // world_from_root: yaw wobble and horizontal drift.
  const double yaw =
      (path.yaw0_deg + options.root_yaw_wobble_deg * std::sin(2 * M_PI * a + path.phase)) *
      kDegToRad;
  out.world_from_root.linear() =
      Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix();
  out.world_from_root.translation() =
      options.root_drift *
      Eigen::Vector3d(std::sin(M_PI * a + path.phase), 0, std::cos(M_PI * a + path.phase) - 1);
  // Look at the posed object's bounding-box centre.
  const Eigen::Matrix3Xd posed = PosedVerticesInRoot(rig, plan, out.animation_time);
  const Eigen::Vector3d centre_root =
      0.5 * (posed.rowwise().minCoeff() + posed.rowwise().maxCoeff());
  const Eigen::Vector3d target = out.world_from_root * centre_root;
  const double az = (path.azimuth0_deg + path.sweep_deg * a) * kDegToRad;
  const double el =
      (path.elevation_deg + options.elevation_wobble_deg * std::sin(2 * M_PI * a + path.phase)) *
      kDegToRad;
  const Eigen::Vector3d eye =
      target + path.distance * Eigen::Vector3d(std::cos(el) * std::sin(az), std::sin(el),
                                               std::cos(el) * std::cos(az));
  out.camera_from_world = CameraFromWorldLookAt(eye, target);
  return out;
}

namespace {

// Per-frame geometry kept for the second (shading / flow) pass.
struct FrameGeometry {
  Eigen::Matrix3Xd vertices;  // camera coordinates
  Eigen::Matrix3Xd normals;   // camera coordinates
  RasterBuffers raster;
};

// Where the surface point (face, barycentrics) of one frame lands in another.
struct FlowSample {
  cv::Vec2f flow;
  bool valid;
};

FlowSample ComputeFlow(const PinholeCamera& camera, const Eigen::Matrix3Xi& faces, int face,
                       const Eigen::Vector3d& bary, int x, int y, const FrameGeometry& target,
                       double tolerance) {
  const Eigen::Vector3d p = bary[0] * target.vertices.col(faces(0, face)) +
                            bary[1] * target.vertices.col(faces(1, face)) +
                            bary[2] * target.vertices.col(faces(2, face));
  double uv[2];
  ProjectPoint(camera.intrinsics.data(), p.data(), uv);
  FlowSample s;
  s.flow = cv::Vec2f(static_cast<float>(uv[0] - (x + 0.5)), static_cast<float>(uv[1] - (y + 0.5)));
  s.valid = false;
  // Behind the camera, or so close to its plane that the flow is beyond the
  // dataset's half-float range: no correspondence; a finite placeholder.
  constexpr float kMaxFlow = 60000;
  if (p.z() < kMinProjectionDepth || !(std::abs(s.flow[0]) < kMaxFlow) ||
      !(std::abs(s.flow[1]) < kMaxFlow)) {
    s.flow = cv::Vec2f(0, 0);
    return s;
  }
  if (!(uv[0] >= 0 && uv[0] < camera.width && uv[1] >= 0 && uv[1] < camera.height)) return s;
  const int px = static_cast<int>(uv[0]), py = static_cast<int>(uv[1]);
  const int seen = target.raster.face.at<int>(py, px);
  if (seen < 0) return s;  // lands on background: at a silhouette, call it occluded
  if (seen == face) {
    s.valid = true;
    return s;
  }
  // Depth of the visible triangle's plane along the ray through uv (exact
  // sub-pixel position), and the depth buffer at the pixel centre.
  const Eigen::Vector3d a = target.vertices.col(faces(0, seen)),
                        b = target.vertices.col(faces(1, seen)),
                        c = target.vertices.col(faces(2, seen));
  const Eigen::Vector3d n = (b - a).cross(c - a);
  double dir[3];
  PixelToRayDirection(camera.intrinsics.data(), uv, dir);
  const Eigen::Vector3d d(dir[0], dir[1], dir[2]);
  const double denom = n.dot(d);
  const double tol = tolerance * p.z();
  if (std::abs(denom) > 1e-9 * n.norm() * d.norm()) {
    const double z_plane = n.dot(a) / denom;
    if (z_plane > 0 && p.z() <= z_plane + tol) s.valid = true;
  }
  if (p.z() <= target.raster.depth.at<float>(py, px) + tol) s.valid = true;
  return s;
}

// Ground-truth mesh colours: the rig's vertex colours as bytes.
Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic> GroundTruthColours(const Rig& rig) {
  const Eigen::Matrix3Xf vertex_colors = RigVertexColors(rig);
  Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic> gt_colors(3, rig.NumVertices());
  for (int i = 0; i < rig.NumVertices(); ++i) {
    for (int k = 0; k < 3; ++k) {
      gt_colors(k, i) =
          static_cast<std::uint8_t>(std::lround(std::clamp(vertex_colors(k, i), 0.0f, 1.0f) * 255));
    }
  }
  return gt_colors;
}

// What every frame's pictures are made from.
struct FrameImaging {
  const Rig& rig;
  const SynthOptions& options;
  const PinholeCamera& camera;
  const FeatureEmbedding& embedding;
  Eigen::Matrix3Xd rest_root;  // rest vertices in the normalised root frame
  Eigen::Vector3d light;       // unit, camera coordinates
  bool textured = false;       // the rig has a UV per vertex
};

// The unshaded colour of the surface point (face, barycentrics b): vertex
// colour x material (x texture at the interpolated UV).
Eigen::Vector3f SurfaceColour(const FrameImaging& im, int face, const Eigen::Vector3d& b) {
  const Rig& rig = im.rig;
  const int i0 = rig.faces(0, face), i1 = rig.faces(1, face), i2 = rig.faces(2, face);
  const RigMaterial& mat = rig.materials[rig.face_material[face]];
  Eigen::Vector3f c = (b[0] * rig.vertex_colors.col(i0).cast<double>() +
                       b[1] * rig.vertex_colors.col(i1).cast<double>() +
                       b[2] * rig.vertex_colors.col(i2).cast<double>())
                          .cast<float>();
  c = c.cwiseProduct(mat.base_color.head<3>().cast<float>());
  if (mat.texture >= 0 && im.textured) {
    const Eigen::Vector2d uv = b[0] * rig.uvs.col(i0).cast<double>() +
                               b[1] * rig.uvs.col(i1).cast<double>() +
                               b[2] * rig.uvs.col(i2).cast<double>();
    c = c.cwiseProduct(SampleTexture(rig.textures[mat.texture], static_cast<float>(uv[0]),
                                     static_cast<float>(uv[1])));
  }
  return c;
}

// max(0, n.l) at the surface point (face, b) of frame geometry g, with the
// interpolated vertex normal turned towards the camera (l: unit, camera
// coordinates).
double LambertAt(const FrameImaging& im, const FrameGeometry& g, int face, const Eigen::Vector3d& b,
                 const Eigen::Vector3d& light) {
  const Rig& rig = im.rig;
  const int i0 = rig.faces(0, face), i1 = rig.faces(1, face), i2 = rig.faces(2, face);
  Eigen::Vector3d n =
      b[0] * g.normals.col(i0) + b[1] * g.normals.col(i1) + b[2] * g.normals.col(i2);
  const Eigen::Vector3d point =
      b[0] * g.vertices.col(i0) + b[1] * g.vertices.col(i1) + b[2] * g.vertices.col(i2);
  if (n.dot(point) > 0) n = -n;
  const double len = n.norm();
  return len > 0 ? std::max(0.0, n.dot(light) / len) : 0.0;
}

// The colour of the surface point (face, barycentrics b) of frame geometry g:
// SurfaceColour with Lambert + ambient shading.
cv::Vec3b ShadePoint(const FrameImaging& im, const FrameGeometry& g, int face,
                     const Eigen::Vector3d& b) {
  const Eigen::Vector3f c = SurfaceColour(im, face, b);
  const double lambert = LambertAt(im, g, face, b, im.light);
  const double shade = im.options.ambient + (1 - im.options.ambient) * lambert;
  cv::Vec3b px;
  for (int k = 0; k < 3; ++k) {
    px[k] = static_cast<unsigned char>(std::lround(std::clamp(c[k] * shade, 0.0, 1.0) * 255));
  }
  return px;
}

// The feature of the surface point (face, b): the embedding of its rest-pose
// point, plus noise drawn from rng.
FeatureVector PointFeature(const FrameImaging& im, int face, const Eigen::Vector3d& b,
                           std::mt19937_64* rng) {
  const Rig& rig = im.rig;
  const int i0 = rig.faces(0, face), i1 = rig.faces(1, face), i2 = rig.faces(2, face);
  const Eigen::Vector3d rest =
      b[0] * im.rest_root.col(i0) + b[1] * im.rest_root.col(i1) + b[2] * im.rest_root.col(i2);
  FeatureVector e = im.embedding(rest);
  if (im.options.feature_noise > 0) {
    for (int k = 0; k < kFeatureDim; ++k) e[k] += im.options.feature_noise * NormalDraw(*rng);
    e.normalize();
  }
  return e;
}

// RGB, mask, depth and features of frame f of video v (geometry g).
void RenderFrameImages(const FrameImaging& im, int v, int f, const FrameGeometry& g, Frame* frame) {
  const SynthOptions& options = im.options;
  const int w = im.camera.width, h = im.camera.height;
  frame->rgb.create(h, w, CV_8UC3);
  frame->rgb.setTo(cv::Scalar(options.background[0], options.background[1], options.background[2]));
  frame->mask.create(h, w, CV_8UC1);
  frame->mask.setTo(kMaskBackground);
  frame->depth = g.raster.depth.clone();
  cv::Mat features(h, w, CV_32FC(kFeatureDim), cv::Scalar::all(0));
  std::mt19937_64 rng(MixSeed(options.seed, 3, v, f));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int face = g.raster.face.at<int>(y, x);
      if (face < 0) continue;
      frame->mask.at<unsigned char>(y, x) = kMaskObject;
      const Eigen::Vector3d b = g.raster.Barycentrics(x, y);
      frame->rgb.at<cv::Vec3b>(y, x) = ShadePoint(im, g, face, b);
      const FeatureVector e = PointFeature(im, face, b, &rng);
      float* out = features.ptr<float>(y) + static_cast<size_t>(x) * kFeatureDim;
      for (int k = 0; k < kFeatureDim; ++k) out[k] = static_cast<float>(e[k]);
    }
  }
  features.convertTo(frame->features, CV_16F);
}

// Flow of frame f to f + gap and f - gap for every gap where that frame
// exists (geometry: every frame of the video).
void RenderFrameFlows(const FrameImaging& im, const std::vector<int>& flow_gaps, int f,
                      const std::vector<FrameGeometry>& geometry, Frame* frame) {
  const int w = im.camera.width, h = im.camera.height;
  const int nfr = static_cast<int>(geometry.size());
  const FrameGeometry& g = geometry[f];
  for (int gap : flow_gaps) {
    for (int sign : {1, -1}) {
      const int other = f + sign * gap;
      if (other < 0 || other >= nfr) continue;
      cv::Mat flow(h, w, CV_32FC2, cv::Scalar(0, 0));
      FlowField field;
      field.gap = sign * gap;
      field.valid = cv::Mat::zeros(h, w, CV_8UC1);
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          const int face = g.raster.face.at<int>(y, x);
          if (face < 0) continue;
          const FlowSample s =
              ComputeFlow(im.camera, im.rig.faces, face, g.raster.Barycentrics(x, y), x, y,
                          geometry[other], im.options.occlusion_tolerance);
          flow.at<cv::Vec2f>(y, x) = s.flow;
          if (s.valid) field.valid.at<unsigned char>(y, x) = 255;
        }
      }
      flow.convertTo(field.flow, CV_16F);
      frame->flows.push_back(std::move(field));
    }
  }
}

// Dominant skinning node of each face: the node with the largest summed
// weight over the face's three vertices.
std::vector<int> FaceNodes(const Rig& rig) {
  std::vector<int> out(rig.NumFaces(), -1);
  std::vector<std::pair<int, double>> acc;
  for (int f = 0; f < rig.NumFaces(); ++f) {
    acc.clear();
    for (int c = 0; c < 3; ++c) {
      const int vtx = rig.faces(c, f);
      for (int k = 0; k < kMaxVertexInfluences; ++k) {
        const int inf = rig.vertex_influences(k, vtx);
        if (inf < 0) continue;
        const int node = rig.influences[inf].node;
        auto it =
            std::find_if(acc.begin(), acc.end(), [&](const auto& p) { return p.first == node; });
        if (it == acc.end()) {
          acc.emplace_back(node, rig.vertex_weights(k, vtx));
        } else {
          it->second += rig.vertex_weights(k, vtx);
        }
      }
    }
    double best = -1;
    for (const auto& [node, weight] : acc) {
      if (weight > best) {
        best = weight;
        out[f] = node;
      }
    }
  }
  return out;
}

// The pixels of a limb: of the rig nodes whose subtree covers between
// limb_share_min and limb_share_max of the object's pixels (by each visible
// face's dominant node), the one at `pick` in [0, 1) (node order). Empty when
// no node qualifies.
cv::Mat LimbPixels(const Rig& rig, const std::vector<int>& face_node, const cv::Mat& face_map,
                   const CasualOptions& options, double pick, int* chosen) {
  const int nodes = static_cast<int>(rig.nodes.size());
  std::vector<long> count(nodes, 0), subtree(nodes, 0);
  long total = 0;
  for (int y = 0; y < face_map.rows; ++y) {
    const int* fm = face_map.ptr<int>(y);
    for (int x = 0; x < face_map.cols; ++x) {
      if (fm[x] < 0) continue;
      ++total;
      if (face_node[fm[x]] >= 0) ++count[face_node[fm[x]]];
    }
  }
  for (int n = 0; n < nodes; ++n) {
    for (int m = n; m >= 0 && count[n] > 0; m = rig.nodes[m].parent) subtree[m] += count[n];
  }
  std::vector<int> candidates;
  for (int n = 0; n < nodes; ++n) {
    const double share = total > 0 ? static_cast<double>(subtree[n]) / total : 0.0;
    if (subtree[n] > 0 && share >= options.limb_share_min && share <= options.limb_share_max) {
      candidates.push_back(n);
    }
  }
  *chosen = -1;
  if (candidates.empty()) return cv::Mat();
  *chosen =
      candidates[std::min(candidates.size() - 1, static_cast<size_t>(pick * candidates.size()))];
  std::vector<unsigned char> inside(nodes, 0);
  for (int n = 0; n < nodes; ++n) {
    for (int m = n; m >= 0; m = rig.nodes[m].parent) {
      if (m == *chosen) {
        inside[n] = 1;
        break;
      }
    }
  }
  cv::Mat limb = cv::Mat::zeros(face_map.size(), CV_8UC1);
  for (int y = 0; y < face_map.rows; ++y) {
    const int* fm = face_map.ptr<int>(y);
    unsigned char* l = limb.ptr<unsigned char>(y);
    for (int x = 0; x < face_map.cols; ++x) {
      if (fm[x] >= 0 && face_node[fm[x]] >= 0 && inside[face_node[fm[x]]]) l[x] = 255;
    }
  }
  return limb;
}

// What a video's casual frames are made from.
struct CasualContext {
  const ScenePlan& plan;
  const CasualVideo& look;
  BackgroundWorld world;
  const std::vector<int>& face_node;
};

// Realism casual: RGB (world, shadow, shaded object, motion blur, exposure,
// white balance, noise, JPEG), degraded mask, exact mask and depth of frame f
// of video v (geometry g at the frame's instant).
void RenderCasualFrame(const FrameImaging& im, const CasualContext& ctx, int v, int f,
                       const FrameGeometry& g, Frame* frame, CasualFrameRecord* record) {
  const SynthOptions& options = im.options;
  const CasualOptions& co = options.casual;
  const CasualVideo& look = ctx.look;
  const int w = im.camera.width, h = im.camera.height;
  frame->depth = g.raster.depth.clone();
  frame->mask_gt = cv::Mat(h, w, CV_8UC1, cv::Scalar(kMaskBackground));
  frame->mask_gt.setTo(kMaskObject, g.raster.face >= 0);
  // Radiance averaged over the sub-frames of the shutter interval.
  cv::Mat radiance(h, w, CV_32FC3, cv::Scalar::all(0));
  const int subframes = co.blur_subframes;
  for (int k = 0; k < subframes; ++k) {
    const double offset = subframes == 1 ? 0.0 : co.shutter * ((k + 0.5) / subframes - 0.5);
    const FrameCameras cams = CamerasAt(im.rig, ctx.plan, options, v, f + offset);
    const Eigen::Matrix3Xd posed = PosedVerticesInRoot(im.rig, ctx.plan, cams.animation_time);
    FrameGeometry moved;
    const FrameGeometry* geo = &g;
    if (offset != 0) {
      moved.vertices = (cams.camera_from_world * cams.world_from_root) * posed;
      moved.normals = VertexNormals(moved.vertices, im.rig.faces);
      moved.raster = Rasterize(im.camera, moved.vertices, im.rig.faces);
      geo = &moved;
    }
    cv::Mat sub(h, w, CV_32FC3, cv::Scalar::all(0));
    if (co.background) {
      cv::Mat shadow;
      if (co.shadow) {
        const Eigen::Matrix3Xd flat =
            ProjectOntoGround(cams.world_from_root * posed, ctx.world.ground_y, look.light_world);
        const RasterBuffers cast =
            Rasterize(im.camera, cams.camera_from_world * flat, im.rig.faces);
        shadow = cv::Mat::zeros(h, w, CV_32FC1);
        shadow.setTo(1.0f, cast.face >= 0);
        const double sigma = std::max(0.5, 0.006 * w);
        cv::GaussianBlur(shadow, shadow, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
      }
      sub = RenderBackground(ctx.world, im.camera, cams.camera_from_world, look.light_world,
                             look.ambient, shadow, co.shadow_strength);
    }
    const Eigen::Vector3d light = cams.camera_from_world.linear() * look.light_world;
    for (int y = 0; y < h; ++y) {
      cv::Vec3f* row = sub.ptr<cv::Vec3f>(y);
      const int* fm = geo->raster.face.ptr<int>(y);
      for (int x = 0; x < w; ++x) {
        if (fm[x] < 0) continue;  // the background stays only where no object is
        const Eigen::Vector3d b = geo->raster.Barycentrics(x, y);
        const Eigen::Vector3f c = SurfaceColour(im, fm[x], b);
        const double shade =
            look.ambient + (1 - look.ambient) * LambertAt(im, *geo, fm[x], b, light);
        row[x] = cv::Vec3f(static_cast<float>(c[0] * shade), static_cast<float>(c[1] * shade),
                           static_cast<float>(c[2] * shade));
      }
    }
    radiance += sub;
  }
  if (subframes > 1) radiance *= 1.0 / subframes;
  // Camera: exposure and white balance, sensor noise, 8 bits, JPEG.
  cv::Mat signal;
  radiance.convertTo(signal, CV_32FC3, 255.0 * look.exposure);
  signal =
      signal.mul(cv::Scalar(look.white_balance[0], look.white_balance[1], look.white_balance[2]));
  if (co.noise_read > 0 || co.noise_shot > 0) {
    std::mt19937_64 noise_rng(MixSeed(options.seed, kStreamSensorNoise, v, f));
    AddSensorNoise(&signal, co.noise_read, co.noise_shot, look.noise_gain, noise_rng);
  }
  signal.convertTo(frame->rgb, CV_8UC3);  // rounds and saturates
  if (co.jpeg_quality > 0) frame->rgb = JpegRoundTrip(frame->rgb, co.jpeg_quality);
  // Mask as a segmenter would give it.
  std::mt19937_64 mask_rng(MixSeed(options.seed, kStreamMask, v, f));
  const bool drop = UniformDraw(mask_rng) < co.limb_drop_rate;
  const double pick = UniformDraw(mask_rng);
  cv::Mat limb;
  if (drop) limb = LimbPixels(im.rig, ctx.face_node, g.raster.face, co, pick, &record->limb_node);
  MaskDegradation degraded = DegradeMask(frame->mask_gt, limb, co, mask_rng);
  frame->mask = degraded.mask;
  record->limb_pixels = degraded.limb_pixels;
  record->holes = static_cast<int>(degraded.holes.size());
  record->boundary_amplitude = degraded.boundary_amplitude;
}

// Video v of the scene: the frames' data and the ground-truth meshes.
void RenderVideo(const FrameImaging& im, const ScenePlan& plan, int v,
                 const Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic>& gt_colors,
                 SynthScene* scene) {
  const Rig& rig = im.rig;
  const int nfr = im.options.frames_per_video;
  Video& video = scene->dataset.videos[v];
  char name[32];
  std::snprintf(name, sizeof(name), "video_%03d", v);
  video.name = name;
  video.camera = im.camera;
  video.frames.resize(nfr);
  scene->gt_meshes[v].resize(nfr);
  std::vector<FrameGeometry> geometry(nfr);
  std::vector<double> lowest(nfr);  // lowest posed point (root y = world y)
  // Pass 1: pose, transform, rasterise.
  ParallelFor(nfr, [&](int begin, int end) {
    for (int f = begin; f < end; ++f) {
      const FramePlan& fp = plan.frames[v][f];
      const Eigen::Matrix3Xd posed = PosedVerticesInRoot(rig, plan, fp.animation_time);
      lowest[f] = posed.row(1).minCoeff();
      const Eigen::Isometry3d camera_from_root = IsometryFromPose(fp.camera_from_root_gt.data());
      FrameGeometry& g = geometry[f];
      g.vertices = camera_from_root * posed;
      g.normals = VertexNormals(g.vertices, rig.faces);
      g.raster = Rasterize(im.camera, g.vertices, rig.faces);
      TriangleMesh& mesh = scene->gt_meshes[v][f];
      mesh.vertices = g.vertices;
      mesh.faces = rig.faces;
      mesh.colors = gt_colors;
    }
  });
  const bool casual = im.options.realism == Realism::kCasual;
  std::vector<int> face_node;
  std::optional<CasualContext> ctx;
  if (casual) {
    face_node = FaceNodes(rig);
    const double ground = *std::min_element(lowest.begin(), lowest.end());
    ctx.emplace(CasualContext{plan, plan.casual[v], DrawBackgroundWorld(im.options.seed, v, ground),
                              face_node});
    scene->casual[v].resize(nfr);
    // The dataset assumes what `banmo prepare` assumes without --intrinsics;
    // the truth is kept as ground truth.
    const double assumed = std::max(im.camera.width, im.camera.height);
    video.camera.intrinsics =
        Eigen::Vector4d(assumed, assumed, 0.5 * im.camera.width, 0.5 * im.camera.height);
    video.intrinsics_gt = im.camera.intrinsics;
  }
  // Pass 2: images, features and flow.
  ParallelFor(nfr, [&](int begin, int end) {
    for (int f = begin; f < end; ++f) {
      Frame& frame = video.frames[f];
      frame.index = f;
      // The root frame moved so that the old origin sits at root_offset:
      // camera_from_new = camera_from_old * T(-root_offset).
      frame.root_pose_gt =
          PoseWithOriginAt(plan.frames[v][f].camera_from_root_gt, -im.options.root_offset);
      frame.root_pose_init =
          PoseWithOriginAt(plan.frames[v][f].camera_from_root_init, -im.options.root_offset);
      if (casual) {
        RenderCasualFrame(im, *ctx, v, f, geometry[f], &frame, &scene->casual[v][f]);
      } else {
        RenderFrameImages(im, v, f, geometry[f], &frame);
      }
      RenderFrameFlows(im, scene->dataset.flow_gaps, f, geometry, &frame);
    }
  });
}

// Records the initial poses' noise in each video's root_poses_init.txt
// (comment lines).
void RecordPoseNoise(const SynthOptions& options, SynthScene* scene) {
  const PoseNoiseStats all = MeasurePoseNoise(scene->dataset);
  auto line = [](const char* what, const PoseNoiseStats& st) {
    char buffer[320];
    std::snprintf(buffer, sizeof(buffer),
                  "%s (%d frames): rotation error mean %.3f deg, p90 %.3f deg, max %.3f deg; "
                  "translation error mean %.6g, p90 %.6g",
                  what, st.frames, st.rotation_mean_deg, st.rotation_p90_deg, st.rotation_max_deg,
                  st.translation_mean, st.translation_p90);
    return std::string(buffer);
  };
  for (int v = 0; v < options.num_videos; ++v) {
    scene->dataset.videos[v].root_poses_init_comment =
        "banmo synth pose noise: " + DescribePoseNoise(options) + ", seed " +
        std::to_string(options.seed) + "\nmeasured against root_poses_gt.txt\n" +
        line("this video", MeasurePoseNoise(scene->dataset, v)) + "\n" + line("all videos", all);
  }
}

}  // namespace

SynthScene RenderSyntheticScene(const Rig& rig, const SynthOptions& options,
                                const std::function<void(int, int)>& progress) {
  const ScenePlan plan = PlanScene(rig, options);
  const FeatureEmbedding embedding;
  Eigen::Matrix3Xd rest_root = rig.rest_vertices;
  rest_root.colwise() -= plan.normalization.center;
  rest_root *= plan.normalization.scale;
  const FrameImaging im{rig,
                        options,
                        plan.camera,
                        embedding,
                        std::move(rest_root),
                        options.light_in_camera.normalized(),
                        rig.uvs.cols() == rig.NumVertices()};
  const Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic> gt_colors = GroundTruthColours(rig);

  SynthScene scene;
  scene.dataset.flow_gaps = options.flow_gaps;
  std::sort(scene.dataset.flow_gaps.begin(), scene.dataset.flow_gaps.end());
  scene.dataset.videos.resize(options.num_videos);
  scene.gt_meshes.resize(options.num_videos);
  if (options.realism == Realism::kCasual) scene.casual.resize(options.num_videos);
  for (int v = 0; v < options.num_videos; ++v) {
    if (options.realism == Realism::kCasual) {
      // Each video has its own focal length.
      const FrameImaging video_im{rig,          options,  plan.cameras[v], embedding,
                                  im.rest_root, im.light, im.textured};
      RenderVideo(video_im, plan, v, gt_colors, &scene);
    } else {
      RenderVideo(im, plan, v, gt_colors, &scene);
    }
    if (progress) progress(v + 1, options.num_videos);
  }
  if (options.object_scale != 1.0) ScaleScene(options.object_scale, &scene);
  if (options.realism == Realism::kCasual) {
    // No rough root poses: what `banmo prepare --roots-on-axis` writes without --poses.
    for (Video& video : scene.dataset.videos) {
      for (Frame& frame : video.frames) {
        frame.root_pose_init = PoseIdentity();
        frame.root_pose_init[kPoseT + 2] = options.camera_distance * options.object_scale;
      }
    }
  }
  if (options.pose_noise_deg > 0 || options.pose_noise_model != PoseNoiseModel::kExact) {
    RecordPoseNoise(options, &scene);
  }
  return scene;
}

PoseNoiseStats MeasurePoseNoise(const Dataset& dataset, int video) {
  CHECK(video >= -1 && video < static_cast<int>(dataset.videos.size())) << "video " << video;
  std::vector<double> rotation, translation;
  for (int v = 0; v < static_cast<int>(dataset.videos.size()); ++v) {
    if (video >= 0 && v != video) continue;
    for (const Frame& frame : dataset.videos[v].frames) {
      if (!frame.root_pose_gt) continue;
      const Pose& gt = *frame.root_pose_gt;
      rotation.push_back(RotationAngleBetween(frame.root_pose_init.data(), gt.data()) / kDegToRad);
      translation.push_back((frame.root_pose_init.tail<3>() - gt.tail<3>()).norm());
    }
  }
  PoseNoiseStats st;
  st.frames = static_cast<int>(rotation.size());
  if (rotation.empty()) return st;
  auto mean = [](const std::vector<double>& x) {
    double sum = 0;
    for (double e : x) sum += e;
    return sum / x.size();
  };
  auto p90 = [](std::vector<double> x) {
    std::sort(x.begin(), x.end());
    const size_t rank = static_cast<size_t>(std::ceil(0.9 * x.size()));
    return x[std::max<size_t>(rank, 1) - 1];
  };
  st.rotation_mean_deg = mean(rotation);
  st.rotation_p90_deg = p90(rotation);
  st.rotation_max_deg = *std::max_element(rotation.begin(), rotation.end());
  st.translation_mean = mean(translation);
  st.translation_p90 = p90(translation);
  return st;
}

std::string DescribePoseNoise(const SynthOptions& options) {
  options.Check();
  char buffer[256];
  if (options.pose_noise_model == PoseNoiseModel::kExact) {
    std::snprintf(buffer, sizeof(buffer), "exact, %g deg about a random axis, translation kept",
                  options.pose_noise_deg);
  } else {
    const double sigma = GaussianNoiseSigma(options.pose_noise_deg * kDegToRad) / kDegToRad;
    std::snprintf(
        buffer, sizeof(buffer),
        "gaussian, mean %g deg (per-axis sigma %.4f deg), translation reset to (0, 0, %g)",
        options.pose_noise_deg, sigma, options.camera_distance * options.object_scale);
  }
  return buffer;
}

void ScaleScene(double s, SynthScene* scene) {
  CHECK(s > 0 && std::isfinite(s)) << "scale " << s;
  for (Video& video : scene->dataset.videos) {
    for (Frame& frame : video.frames) {
      frame.root_pose_init.tail<3>() *= s;
      if (frame.root_pose_gt) frame.root_pose_gt->tail<3>() *= s;
      if (!frame.depth.empty()) frame.depth *= s;
    }
  }
  for (auto& meshes : scene->gt_meshes) {
    for (TriangleMesh& mesh : meshes) mesh.vertices *= s;
  }
}

}  // namespace banmo::synth
