#include "banmo/synth/realism.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "banmo/synth/features.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo::synth {

void CasualOptions::Check() const {
  auto fail = [](const char* field, const std::string& expected) {
    ThrowInputError("casual realism option ", field, ": expected ", expected);
  };
  if (!(focal_min > 0.05 && focal_min <= focal_max && focal_max <= 20)) {
    fail("focal_min/focal_max", "0.05 < min <= max <= 20");
  }
  if (!(shadow_strength >= 0 && shadow_strength <= 1)) fail("shadow_strength", "in [0, 1]");
  if (!(ambient_min >= 0 && ambient_min <= ambient_max && ambient_max <= 1)) {
    fail("ambient_min/ambient_max", "0 <= min <= max <= 1");
  }
  if (!(light_elevation_min_deg >= 5 && light_elevation_min_deg <= light_elevation_max_deg &&
        light_elevation_max_deg <= 90)) {
    fail("light_elevation_min_deg/max", "5 <= min <= max <= 90");
  }
  if (!(exposure_min > 0 && exposure_min <= exposure_max && exposure_max <= 10)) {
    fail("exposure_min/exposure_max", "0 < min <= max <= 10");
  }
  if (!(white_balance >= 0 && white_balance < 1)) fail("white_balance", "in [0, 1)");
  if (!(noise_read >= 0 && noise_read <= 100)) fail("noise_read", "in [0, 100]");
  if (!(noise_shot >= 0 && noise_shot <= 100)) fail("noise_shot", "in [0, 100]");
  if (!(noise_gain_min >= 0 && noise_gain_min <= noise_gain_max && noise_gain_max <= 100)) {
    fail("noise_gain_min/noise_gain_max", "0 <= min <= max <= 100");
  }
  if (blur_subframes < 1 || blur_subframes > 64) fail("blur_subframes", "in [1, 64]");
  if (!(shutter >= 0 && shutter <= 1)) fail("shutter", "in [0, 1]");
  if (jpeg_quality < 0 || jpeg_quality > 100) fail("jpeg_quality", "in [0, 100] (0: no JPEG)");
  if (!(mask_boundary_px >= 0 && mask_boundary_px <= 50)) fail("mask_boundary_px", "in [0, 50]");
  if (!(mask_boundary_smooth_px >= 0.5 && mask_boundary_smooth_px <= 100)) {
    fail("mask_boundary_smooth_px", "in [0.5, 100]");
  }
  if (mask_holes_max < 0 || mask_holes_max > 100) fail("mask_holes_max", "in [0, 100]");
  if (!(mask_hole_radius_max_px >= 0.7 && mask_hole_radius_max_px <= 50)) {
    fail("mask_hole_radius_max_px", "in [0.7, 50]");
  }
  if (!(limb_drop_rate >= 0 && limb_drop_rate <= 1)) fail("limb_drop_rate", "in [0, 1]");
  if (!(limb_share_min >= 0 && limb_share_min <= limb_share_max && limb_share_max <= 1)) {
    fail("limb_share_min/limb_share_max", "0 <= min <= max <= 1");
  }
}

CasualVideo DrawCasualVideo(const CasualOptions& options, std::uint64_t seed, int video) {
  std::mt19937_64 rng(MixSeed(seed, kStreamCasualVideo, static_cast<std::uint64_t>(video)));
  CasualVideo c;
  c.focal_factor = options.focal_min + UniformDraw(rng) * (options.focal_max - options.focal_min);
  const double azimuth = 2 * M_PI * UniformDraw(rng);
  const double elevation =
      (options.light_elevation_min_deg +
       UniformDraw(rng) * (options.light_elevation_max_deg - options.light_elevation_min_deg)) *
      M_PI / 180;
  c.light_world = Eigen::Vector3d(std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
                                  std::cos(elevation) * std::cos(azimuth));
  c.ambient = options.ambient_min + UniformDraw(rng) * (options.ambient_max - options.ambient_min);
  c.exposure = options.exposure_min *
               std::exp(UniformDraw(rng) * std::log(options.exposure_max / options.exposure_min));
  const double wr = 1 + options.white_balance * (2 * UniformDraw(rng) - 1);
  const double wb = 1 + options.white_balance * (2 * UniformDraw(rng) - 1);
  c.white_balance = Eigen::Vector3d(wr, 1, wb);
  c.noise_gain =
      options.noise_gain_min + UniformDraw(rng) * (options.noise_gain_max - options.noise_gain_min);
  return c;
}

namespace {

// Hash of a lattice point to [0, 1): the indices mixed into the seed with
// odd constants, then MurmurHash3's 64-bit finaliser (inlined: the textures
// take several per pixel).
inline double Hash01(std::uint64_t seed, std::int64_t i, std::int64_t j, std::uint64_t salt) {
  std::uint64_t h = seed ^ (static_cast<std::uint64_t>(i) * 0x9E3779B97F4A7C15ULL) ^
                    (static_cast<std::uint64_t>(j) * 0xC2B2AE3D27D4EB4FULL) ^
                    (salt * 0x165667B19E3779F9ULL);
  h ^= h >> 33;
  h *= 0xFF51AFD7ED558CCDULL;
  h ^= h >> 33;
  h *= 0xC4CEB9FE1A85EC53ULL;
  h ^= h >> 33;
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

// Value noise in [0, 1]: lattice hashes, smoothstep-interpolated.
double ValueNoise(std::uint64_t seed, std::uint64_t salt, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  double u = x - fx, v = y - fy;
  u = u * u * (3 - 2 * u);
  v = v * v * (3 - 2 * v);
  const double a = Hash01(seed, ix, iy, salt), b = Hash01(seed, ix + 1, iy, salt);
  const double c = Hash01(seed, ix, iy + 1, salt), d = Hash01(seed, ix + 1, iy + 1, salt);
  return (a * (1 - u) + b * u) * (1 - v) + (c * (1 - u) + d * u) * v;
}

// Fractal sum of `octaves` value noises (frequency x2, amplitude x0.5), in [0, 1].
double Fbm(std::uint64_t seed, std::uint64_t salt, double x, double y, int octaves) {
  double sum = 0, norm = 0, amp = 1;
  for (int o = 0; o < octaves; ++o) {
    sum += amp * ValueNoise(seed, salt + o, x, y);
    norm += amp;
    amp *= 0.5;
    x *= 2.0;
    y *= 2.0;
  }
  return sum / norm;
}

// A saturated colour from three hashes (hue, saturation, value).
Eigen::Vector3d HashColour(double h, double s, double v) {
  s = 0.35 + 0.6 * s;
  v = 0.25 + 0.7 * v;
  const double hh = 6 * h;
  const int sector = std::min(5, static_cast<int>(hh));
  const double f = hh - sector;
  const double p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  switch (sector) {
    case 0:
      return {v, t, p};
    case 1:
      return {q, v, p};
    case 2:
      return {p, v, t};
    case 3:
      return {p, q, v};
    case 4:
      return {t, p, v};
    default:
      return {v, p, q};
  }
}

Eigen::Vector3d Mix(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t) {
  return (1 - t) * a + t * b;
}

// Floor colour at world (x, z).
Eigen::Vector3d FloorColour(const BackgroundWorld& w, double x, double z) {
  Eigen::Vector3d c = Mix(w.floor_a, w.floor_b, Fbm(w.seed, 10, 0.8 * x, 0.8 * z, 4));
  if (w.tile_size > 0) {
    const double tx = x / w.tile_size, tz = z / w.tile_size;
    const double fx = tx - std::floor(tx), fz = tz - std::floor(tz);
    const double edge = std::min({fx, 1 - fx, fz, 1 - fz});
    if (edge < 0.04) {
      c *= 0.55;
    } else {
      c *= 0.82 + 0.36 * Hash01(w.seed, static_cast<std::int64_t>(std::floor(tx)),
                                static_cast<std::int64_t>(std::floor(tz)), 20);
    }
  }
  c = Mix(c, w.floor_grain, 0.35 * Fbm(w.seed, 30, 7 * x, 7 * z, 2));
  // Clutter: at most one disc per 0.6-unit cell (stones, leaves, toys).
  const double cell = 0.6;
  const auto cx = static_cast<std::int64_t>(std::floor(x / cell));
  const auto cz = static_cast<std::int64_t>(std::floor(z / cell));
  for (std::int64_t i = cx - 1; i <= cx + 1; ++i) {
    for (std::int64_t j = cz - 1; j <= cz + 1; ++j) {
      if (Hash01(w.seed, i, j, 40) >= w.clutter) continue;
      const double px = (i + Hash01(w.seed, i, j, 41)) * cell;
      const double pz = (j + Hash01(w.seed, i, j, 42)) * cell;
      const double r = 0.05 + 0.22 * Hash01(w.seed, i, j, 43);
      const double d = std::sqrt((x - px) * (x - px) + (z - pz) * (z - pz));
      if (d < r) {
        const Eigen::Vector3d col = HashColour(Hash01(w.seed, i, j, 44), Hash01(w.seed, i, j, 45),
                                               Hash01(w.seed, i, j, 46));
        return col * (0.75 + 0.25 * (1 - d / r));
      }
    }
  }
  return c;
}

// Backdrop colour at arc length u and height h above the ground.
Eigen::Vector3d WallColour(const BackgroundWorld& w, double u, double h) {
  Eigen::Vector3d c = Mix(w.wall_a, w.wall_b, Fbm(w.seed, 50, 0.5 * u, 0.5 * h, 3));
  // Upright clutter (furniture, bushes, posts), front to back by cell order.
  const double cell = 1.1;
  const auto k = static_cast<std::int64_t>(std::floor(u / cell));
  for (std::int64_t i = k - 1; i <= k + 1; ++i) {
    for (std::int64_t layer = 0; layer < 2; ++layer) {
      if (Hash01(w.seed, i, layer, 60) >= 0.75) continue;
      const double u0 = (i + 0.7 * Hash01(w.seed, i, layer, 61)) * cell;
      const double u1 = u0 + (0.25 + 1.1 * Hash01(w.seed, i, layer, 62)) * cell;
      const double h0 = layer == 0 ? 0.0 : 1.2 + 1.8 * Hash01(w.seed, i, layer, 63);
      const double h1 = h0 + 0.3 + 2.2 * Hash01(w.seed, i, layer, 64);
      if (u < u0 || u > u1 || h < h0 || h > h1) continue;
      Eigen::Vector3d col = HashColour(Hash01(w.seed, i, layer, 65), Hash01(w.seed, i, layer, 66),
                                       Hash01(w.seed, i, layer, 67));
      if (Hash01(w.seed, i, layer, 68) < 0.35) {  // striped (shelves, blinds)
        const double stripes = std::sin(2 * M_PI * h * (3 + 5 * Hash01(w.seed, i, layer, 69)));
        col *= stripes > 0 ? 1.0 : 0.6;
      }
      return col * (0.7 + 0.3 * Fbm(w.seed, 70, 3 * u, 3 * h, 2));
    }
  }
  return c;
}

}  // namespace

BackgroundWorld DrawBackgroundWorld(std::uint64_t seed, int video, double ground_y) {
  std::mt19937_64 rng(MixSeed(seed, kStreamBackground, static_cast<std::uint64_t>(video)));
  BackgroundWorld w;
  w.ground_y = ground_y;
  w.seed = rng();
  // Floors: grass, dirt, pavement, wood, carpet, sand.
  static const double kFloors[6][2][3] = {
      {{0.20, 0.38, 0.12}, {0.36, 0.50, 0.20}}, {{0.40, 0.30, 0.20}, {0.58, 0.46, 0.32}},
      {{0.42, 0.42, 0.40}, {0.60, 0.59, 0.56}}, {{0.45, 0.29, 0.15}, {0.62, 0.43, 0.25}},
      {{0.45, 0.18, 0.18}, {0.30, 0.22, 0.40}}, {{0.70, 0.62, 0.45}, {0.80, 0.74, 0.58}}};
  // Backdrops: plaster, hedge, brick, painted wall, wood panels.
  static const double kWalls[5][2][3] = {{{0.78, 0.75, 0.68}, {0.88, 0.86, 0.80}},
                                         {{0.12, 0.30, 0.10}, {0.25, 0.42, 0.18}},
                                         {{0.52, 0.25, 0.18}, {0.66, 0.38, 0.28}},
                                         {{0.35, 0.50, 0.62}, {0.48, 0.60, 0.70}},
                                         {{0.50, 0.36, 0.22}, {0.36, 0.24, 0.14}}};
  auto jitter = [&](const double* c) {
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k)
      v[k] = std::clamp(c[k] + 0.08 * (2 * UniformDraw(rng) - 1), 0.0, 1.0);
    return v;
  };
  const int floor = std::min(5, static_cast<int>(6 * UniformDraw(rng)));
  w.floor_a = jitter(kFloors[floor][0]);
  w.floor_b = jitter(kFloors[floor][1]);
  w.floor_grain = jitter(kFloors[(floor + 2) % 6][1]);
  const int wall = std::min(4, static_cast<int>(5 * UniformDraw(rng)));
  w.wall_a = jitter(kWalls[wall][0]);
  w.wall_b = jitter(kWalls[wall][1]);
  w.sky_top = Eigen::Vector3d(0.35, 0.55, 0.9) * (0.8 + 0.2 * UniformDraw(rng));
  w.sky_horizon = Eigen::Vector3d(0.85, 0.88, 0.92);
  w.tile_size = UniformDraw(rng) < 0.4 ? 0.3 + 0.6 * UniformDraw(rng) : 0.0;
  w.clutter = 0.25 + 0.5 * UniformDraw(rng);
  w.radius = 8 + 4 * UniformDraw(rng);
  w.height = 3 + 3 * UniformDraw(rng);
  return w;
}

cv::Mat RenderBackground(const BackgroundWorld& world, const PinholeCamera& camera,
                         const Eigen::Isometry3d& camera_from_world,
                         const Eigen::Vector3d& light_world, double ambient, const cv::Mat& shadow,
                         double shadow_strength) {
  const int w = camera.width, h = camera.height;
  cv::Mat out(h, w, CV_32FC3);
  const Eigen::Isometry3d world_from_camera = camera_from_world.inverse();
  const Eigen::Vector3d eye = world_from_camera.translation();
  const Eigen::Matrix3d rot = world_from_camera.linear();
  const double fx = camera.intrinsics[0], fy = camera.intrinsics[1];
  const double cx = camera.intrinsics[2], cy = camera.intrinsics[3];
  const double sun = std::max(0.0, light_world.y());
  const double r2 = world.radius * world.radius;
  for (int y = 0; y < h; ++y) {
    cv::Vec3f* row = out.ptr<cv::Vec3f>(y);
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector3d d =
          rot * Eigen::Vector3d((x + 0.5 - cx) / fx, (y + 0.5 - cy) / fy, 1.0);
      Eigen::Vector3d c;
      bool done = false;
      if (d.y() < 0) {
        const double t = (world.ground_y - eye.y()) / d.y();
        const Eigen::Vector3d p = eye + t * d;
        if (t > 0 && p.x() * p.x() + p.z() * p.z() < r2) {
          const double s = shadow.empty() ? 0.0 : shadow.at<float>(y, x);
          c = FloorColour(world, p.x(), p.z()) *
              (ambient + (1 - ambient) * sun * (1 - shadow_strength * s));
          done = true;
        }
      }
      if (!done) {
        // The cylinder |xz| = radius (the eye is inside it).
        const double a = d.x() * d.x() + d.z() * d.z();
        const double b = eye.x() * d.x() + eye.z() * d.z();
        const double e = eye.x() * eye.x() + eye.z() * eye.z() - r2;
        const double t = a > 1e-12 ? (-b + std::sqrt(std::max(0.0, b * b - a * e))) / a : -1;
        const Eigen::Vector3d p = eye + t * d;
        const double height = p.y() - world.ground_y;
        if (t > 0 && height < world.height) {
          const Eigen::Vector3d n = Eigen::Vector3d(-p.x(), 0, -p.z()) / world.radius;
          const double lambert = std::max(0.0, n.dot(light_world));
          c = WallColour(world, std::atan2(p.z(), p.x()) * world.radius, height) *
              (ambient + (1 - ambient) * lambert);
        } else {
          const double up = std::clamp(d.normalized().y(), 0.0, 1.0);
          c = Mix(world.sky_horizon, world.sky_top, std::sqrt(up));
          const double cloud =
              Fbm(world.seed, 80, 3 * d.x() / (0.2 + up), 3 * d.z() / (0.2 + up), 4);
          c = Mix(c, Eigen::Vector3d(0.95, 0.95, 0.95), std::clamp(2 * (cloud - 0.5), 0.0, 1.0));
        }
      }
      row[x] =
          cv::Vec3f(static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]));
    }
  }
  return out;
}

Eigen::Matrix3Xd ProjectOntoGround(const Eigen::Matrix3Xd& world_vertices, double ground_y,
                                   const Eigen::Vector3d& light_world) {
  CHECK(light_world.y() > 0) << "the light must come from above the ground";
  Eigen::Matrix3Xd out = world_vertices;
  for (Eigen::Index i = 0; i < out.cols(); ++i) {
    out.col(i) -= ((out(1, i) - ground_y) / light_world.y()) * light_world;
  }
  return out;
}

void AddSensorNoise(cv::Mat* image, double read, double shot, double gain, std::mt19937_64& rng) {
  CHECK(image->type() == CV_32FC3);
  for (int y = 0; y < image->rows; ++y) {
    float* p = image->ptr<float>(y);
    for (int i = 0; i < image->cols * 3; ++i) {
      const double sigma = gain * std::sqrt(read * read + shot * std::max(0.0f, p[i]));
      p[i] = static_cast<float>(p[i] + sigma * NormalDraw(rng));
    }
  }
}

cv::Mat JpegRoundTrip(const cv::Mat& rgb, int quality) {
  CHECK(rgb.type() == CV_8UC3);
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<unsigned char> bytes;
  CHECK(cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, quality}))
      << "JPEG encoding failed";
  const cv::Mat decoded = cv::imdecode(bytes, cv::IMREAD_COLOR);
  CHECK(!decoded.empty() && decoded.size() == rgb.size()) << "JPEG decoding failed";
  cv::Mat out;
  cv::cvtColor(decoded, out, cv::COLOR_BGR2RGB);
  return out;
}

MaskDegradation DegradeMask(const cv::Mat& exact, const cv::Mat& limb, const CasualOptions& options,
                            std::mt19937_64& rng) {
  CHECK(exact.type() == CV_8UC1);
  const int w = exact.cols, h = exact.rows;
  const cv::Mat object = exact == 255;
  cv::Mat dist_in, dist_out;
  cv::distanceTransform(object, dist_in, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::distanceTransform(~object, dist_out, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  MaskDegradation out;
  // 1. Boundary: smooth random displacement.
  out.boundary_amplitude = (0.5 + 0.5 * UniformDraw(rng)) * options.mask_boundary_px;
  cv::Mat field(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y) {
    float* f = field.ptr<float>(y);
    for (int x = 0; x < w; ++x) f[x] = static_cast<float>(NormalDraw(rng));
  }
  cv::GaussianBlur(field, field, cv::Size(0, 0), options.mask_boundary_smooth_px,
                   options.mask_boundary_smooth_px, cv::BORDER_REFLECT);
  // r = amplitude x clamp(field / (1.5 std), -1, 1): most of the boundary
  // moves by a good part of the amplitude, none by more.
  cv::Scalar mean, stddev;
  cv::meanStdDev(field, mean, stddev);
  const double scale = 1.5 * stddev[0];
  out.mask = cv::Mat::zeros(h, w, CV_8UC1);
  for (int y = 0; y < h; ++y) {
    const unsigned char* o = object.ptr<unsigned char>(y);
    const float* di = dist_in.ptr<float>(y);
    const float* dout = dist_out.ptr<float>(y);
    const float* f = field.ptr<float>(y);
    unsigned char* m = out.mask.ptr<unsigned char>(y);
    for (int x = 0; x < w; ++x) {
      const double sd = o[x] ? di[x] - 0.5 : -(dout[x] - 0.5);
      const double r =
          scale > 0 ? out.boundary_amplitude * std::clamp(f[x] / scale, -1.0, 1.0) : 0.0;
      m[x] = sd + r > 0 ? 255 : 0;
    }
  }
  // 2. Holes well inside the object.
  const int holes = std::min(options.mask_holes_max,
                             static_cast<int>(UniformDraw(rng) * (options.mask_holes_max + 1)));
  for (int i = 0; i < holes; ++i) {
    const double radius = 0.7 + UniformDraw(rng) * (options.mask_hole_radius_max_px - 0.7);
    const double pick = UniformDraw(rng);
    std::vector<cv::Point> candidates;
    for (int y = 0; y < h; ++y) {
      const float* di = dist_in.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        if (di[x] >= 2 * radius + options.mask_boundary_px + 1) candidates.emplace_back(x, y);
      }
    }
    if (candidates.empty()) continue;
    const cv::Point c =
        candidates[std::min(candidates.size() - 1, static_cast<size_t>(pick * candidates.size()))];
    out.holes.emplace_back(static_cast<float>(c.x + 0.5), static_cast<float>(c.y + 0.5),
                           static_cast<float>(radius));
    const int r = static_cast<int>(std::ceil(radius));
    for (int y = std::max(0, c.y - r); y <= std::min(h - 1, c.y + r); ++y) {
      for (int x = std::max(0, c.x - r); x <= std::min(w - 1, c.x + r); ++x) {
        if (std::hypot(x - c.x, y - c.y) <= radius) out.mask.at<unsigned char>(y, x) = 0;
      }
    }
  }
  // 3. A missing limb.
  if (!limb.empty()) {
    CHECK(limb.type() == CV_8UC1 && limb.size() == exact.size());
    for (int y = 0; y < h; ++y) {
      const unsigned char* l = limb.ptr<unsigned char>(y);
      const unsigned char* o = object.ptr<unsigned char>(y);
      unsigned char* m = out.mask.ptr<unsigned char>(y);
      for (int x = 0; x < w; ++x) {
        if (l[x] == 0) continue;
        if (o[x]) ++out.limb_pixels;
        m[x] = 0;
      }
    }
  }
  return out;
}

}  // namespace banmo::synth
