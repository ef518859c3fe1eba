#include "banmo/optim/ray_sampler.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

RaySampler::RaySampler(const Dataset& dataset) : dataset_(dataset) {
  object_pixels_.resize(dataset.videos.size());
  boundary_pixels_.resize(dataset.videos.size());
  in_boundary_.resize(dataset.videos.size());
  object_box_.resize(dataset.videos.size());
  const cv::Mat kernel = cv::getStructuringElement(
      cv::MORPH_RECT, cv::Size(2 * kBoundaryBandPx + 1, 2 * kBoundaryBandPx + 1));
  for (size_t v = 0; v < dataset.videos.size(); ++v) {
    const Video& video = dataset.videos[v];
    object_pixels_[v].resize(video.frames.size());
    boundary_pixels_[v].resize(video.frames.size());
    in_boundary_[v].resize(video.frames.size());
    object_box_[v].resize(video.frames.size());
    for (size_t t = 0; t < video.frames.size(); ++t) {
      const Frame& f = video.frames[t];
      if (f.skip) continue;
      frames_.push_back({static_cast<int>(v), static_cast<int>(t)});
      // Edge band: object pixels near background and background pixels
      // near the object (ignored pixels are neither).
      const cv::Mat object = f.mask == kMaskObject, background = f.mask == kMaskBackground;
      cv::Mat near_object, near_background;
      cv::dilate(object, near_object, kernel);
      cv::dilate(background, near_background, kernel);
      cv::Mat& band = in_boundary_[v][t];
      band = (object & near_background) | (background & near_object);
      std::vector<int>& pixels = object_pixels_[v][t];
      std::vector<int>& edge = boundary_pixels_[v][t];
      for (int y = 0; y < f.mask.rows; ++y) {
        const unsigned char* row = f.mask.ptr<unsigned char>(y);
        const unsigned char* in_band = band.ptr<unsigned char>(y);
        for (int x = 0; x < f.mask.cols; ++x) {
          if (row[x] == kMaskObject) pixels.push_back(y * f.mask.cols + x);
          if (in_band[x] != 0) edge.push_back(y * f.mask.cols + x);
        }
      }
      if (!pixels.empty()) object_box_[v][t] = cv::boundingRect(object);
    }
  }
  CHECK(!frames_.empty()) << "the dataset has no usable frame";
}

Ray RaySampler::MakeRay(int v, int t, int x, int y, int samples_per_ray,
                        const SamplingConfig& sampling, const Model& model,
                        const Eigen::AlignedBox3d& canonical_bounds, std::mt19937* rng) const {
  const Video& video = dataset_.videos[v];
  const Frame& f = video.frames[t];
  Ray ray;
  ray.video = v;
  ray.frame = t;
  ray.uv = Eigen::Vector2d(x + 0.5, y + 0.5);
  const cv::Vec3b c = f.rgb.at<cv::Vec3b>(y, x);
  ray.rgb = Eigen::Vector3d(c[0], c[1], c[2]) / 255.0;
  const unsigned char m = f.mask.at<unsigned char>(y, x);
  ray.mask = m == kMaskObject ? 1.0 : (m == kMaskBackground ? 0.0 : -1.0);
  // Flow partner: a random configured gap and direction with data.
  std::vector<int> gaps;
  for (int g : sampling.flow_gaps) {
    for (int dir : {1, -1}) {
      const int partner = t + dir * g;
      if (partner < 0 || partner >= static_cast<int>(video.frames.size())) continue;
      if (video.frames[partner].skip || f.FlowForGap(dir * g) == nullptr) continue;
      gaps.push_back(dir * g);
    }
  }
  if (!gaps.empty()) {
    const int gap = gaps[std::uniform_int_distribution<int>(0, gaps.size() - 1)(*rng)];
    const FlowField* flow = f.FlowForGap(gap);
    if (flow->valid.at<unsigned char>(y, x) != 0) {
      const cv::Vec<cv::float16_t, 2> d = flow->flow.at<cv::Vec<cv::float16_t, 2>>(y, x);
      ray.partner_frame = t + gap;
      ray.has_flow = true;
      ray.flow = Eigen::Vector2d(static_cast<float>(d[0]), static_cast<float>(d[1]));
    }
  }
  if (!f.features.empty() && ray.mask > 0.5) {
    const cv::float16_t* feat = f.features.ptr<cv::float16_t>(y) + kFeatureDim * x;
    for (int k = 0; k < kFeatureDim; ++k) ray.feature[k] = static_cast<float>(feat[k]);
    ray.has_feature = IsPixelFeature(feat);
  }
  if (sampling.unbiased_silhouette && ray.mask >= 0.0) {
    ray.silhouette_weight = PixelWeight(v, t, x, y, sampling);
  }
  double near, far;
  const Pose camera_from_root = model.RootPose(v, t);
  NearFarPlanes(camera_from_root, canonical_bounds, sampling.near_far_margin, &near, &far);
  const Eigen::Vector4d& k = model.video(v).intrinsics;
  if (sampling.clip_to_box) {
    ClipDepthsToBox(camera_from_root, canonical_bounds, sampling.clip_margin, k, ray.uv, &near,
                    &far);
  }
  if (!(std::isfinite(near) && std::isfinite(far) && near < far)) {
    ThrowDivergenceError("the near/far planes (", near, ", ", far, ") of video ", v, " frame ", t,
                         " are not finite and increasing (its root pose or the canonical bounds "
                         "are not finite or too large)");
  }
  ray.samples =
      StratifiedSamples(samples_per_ray, near, far, RayDirectionLength(k, ray.uv), true, rng);
  return ray;
}

std::vector<Ray> RaySampler::Sample(int count, int samples_per_ray, const SamplingConfig& sampling,
                                    const Model& model, const Eigen::AlignedBox3d& bounds,
                                    std::mt19937* rng) const {
  std::vector<Ray> rays;
  rays.reserve(count);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int active =
      error_cache_.empty() ? 0 : static_cast<int>(std::round(sampling.active_fraction * count));
  // Active rays: pixels next to cached large errors (error-proportional).
  if (active > 0) {
    std::vector<double> cumulative(error_cache_.size());
    double total = 0.0;
    for (size_t i = 0; i < error_cache_.size(); ++i) {
      total += error_cache_[i].error;
      cumulative[i] = total;
    }
    std::uniform_int_distribution<int> jitter(-1, 1);
    for (int i = 0; i < active; ++i) {
      const double u = unit(*rng) * total;
      const size_t j = std::min<size_t>(
          std::lower_bound(cumulative.begin(), cumulative.end(), u) - cumulative.begin(),
          error_cache_.size() - 1);
      const CachedPixel& p = error_cache_[j];
      const Frame& f = dataset_.videos[p.video].frames[p.frame];
      const int x = std::clamp(p.x + jitter(*rng), 0, f.mask.cols - 1);
      const int y = std::clamp(p.y + jitter(*rng), 0, f.mask.rows - 1);
      rays.push_back(
          MakeRay(p.video, p.frame, x, y, samples_per_ray, sampling, model, bounds, rng));
    }
  }
  const int num_frames = static_cast<int>(frames_.size());
  if (sampling.frames_per_batch > 0 && sampling.frames_per_batch < num_frames) {
    // A partial Fisher-Yates shuffle picks the batch's distinct frames; the
    // rays go round them in turn, so each gets count / frames_per_batch
    // (the first ones one more).
    std::vector<int> order(num_frames);
    for (int i = 0; i < num_frames; ++i) order[i] = i;
    for (int i = 0; i < sampling.frames_per_batch; ++i) {
      std::swap(order[i], order[std::uniform_int_distribution<int>(i, num_frames - 1)(*rng)]);
    }
    for (int i = 0; static_cast<int>(rays.size()) < count; ++i) {
      const FrameRef fr = frames_[order[i % sampling.frames_per_batch]];
      rays.push_back(RandomRay(fr.video, fr.frame, samples_per_ray, sampling, model, bounds, rng));
    }
    return rays;
  }
  std::uniform_int_distribution<int> pick_frame(0, num_frames - 1);
  while (static_cast<int>(rays.size()) < count) {
    const FrameRef fr = frames_[pick_frame(*rng)];
    rays.push_back(RandomRay(fr.video, fr.frame, samples_per_ray, sampling, model, bounds, rng));
  }
  return rays;
}

std::vector<Ray> RaySampler::SampleFrame(int video, int frame, int count, int samples_per_ray,
                                         const SamplingConfig& sampling, const Model& model,
                                         const Eigen::AlignedBox3d& bounds,
                                         std::mt19937* rng) const {
  CHECK(video >= 0 && video < static_cast<int>(dataset_.videos.size()) && frame >= 0 &&
        frame < static_cast<int>(dataset_.videos[video].frames.size()))
      << "no frame " << frame << " in video " << video;
  std::vector<Ray> rays;
  rays.reserve(count);
  for (int i = 0; i < count; ++i) {
    rays.push_back(RandomRay(video, frame, samples_per_ray, sampling, model, bounds, rng));
  }
  return rays;
}

cv::Rect RaySampler::CropRect(int video, int frame, const SamplingConfig& sampling) const {
  const cv::Mat& mask = dataset_.videos[video].frames[frame].mask;
  const cv::Rect image(0, 0, mask.cols, mask.rows);
  const cv::Rect& box = object_box_[video][frame];
  if (sampling.crop_scale <= 0.0 || box.area() == 0) return image;
  // Scaled about the box's centre, to whole pixels; at least the box itself.
  const double cx = box.x + 0.5 * box.width, cy = box.y + 0.5 * box.height;
  const double hw = 0.5 * box.width * sampling.crop_scale;
  const double hh = 0.5 * box.height * sampling.crop_scale;
  const int x0 = std::min(box.x, static_cast<int>(std::floor(cx - hw)));
  const int y0 = std::min(box.y, static_cast<int>(std::floor(cy - hh)));
  const int x1 = std::max(box.x + box.width, static_cast<int>(std::ceil(cx + hw)));
  const int y1 = std::max(box.y + box.height, static_cast<int>(std::ceil(cy + hh)));
  return cv::Rect(x0, y0, x1 - x0, y1 - y0) & image;
}

// A ray of frame (v, t): inside the mask with probability
// sampling.foreground_fraction, in the edge band with probability
// sampling.boundary_fraction, else uniform over the frame's crop (CropRect).
Ray RaySampler::RandomRay(int v, int t, int samples_per_ray, const SamplingConfig& sampling,
                          const Model& model, const Eigen::AlignedBox3d& bounds,
                          std::mt19937* rng) const {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Frame& f = dataset_.videos[v].frames[t];
  const std::vector<int>& pixels = object_pixels_[v][t];
  const std::vector<int>& edge = boundary_pixels_[v][t];
  int x, y;
  // A frame without object pixels has no edge band either: every draw is
  // uniform (and the random stream the same as before the band existed).
  const double u = pixels.empty() ? 1.0 : unit(*rng);
  if (u < sampling.foreground_fraction) {
    const int p = pixels[std::uniform_int_distribution<int>(0, pixels.size() - 1)(*rng)];
    x = p % f.mask.cols;
    y = p / f.mask.cols;
  } else if (!edge.empty() && u < sampling.foreground_fraction + sampling.boundary_fraction) {
    const int p = edge[std::uniform_int_distribution<int>(0, edge.size() - 1)(*rng)];
    x = p % f.mask.cols;
    y = p / f.mask.cols;
  } else {
    const cv::Rect crop = CropRect(v, t, sampling);
    x = std::uniform_int_distribution<int>(crop.x, crop.x + crop.width - 1)(*rng);
    y = std::uniform_int_distribution<int>(crop.y, crop.y + crop.height - 1)(*rng);
  }
  return MakeRay(v, t, x, y, samples_per_ray, sampling, model, bounds, rng);
}

double RaySampler::PixelWeight(int video, int frame, int x, int y,
                               const SamplingConfig& sampling) const {
  const Frame& f = dataset_.videos[video].frames[frame];
  const cv::Rect crop = CropRect(video, frame, sampling);
  const double n = static_cast<double>(crop.area());
  const double n_object = static_cast<double>(object_pixels_[video][frame].size());
  const double n_edge = static_cast<double>(boundary_pixels_[video][frame].size());
  // A part with no pixels falls back to the uniform draw (RandomRay).
  const double fg = n_object > 0 ? sampling.foreground_fraction : 0.0;
  const double fe = n_edge > 0 ? sampling.boundary_fraction : 0.0;
  CHECK_LT(fg + fe, 1.0) << "no pixel weight when no ray is drawn uniformly";
  // N p(pixel): the uniform part covers the crop only (an edge-band pixel
  // may lie just outside a tight one).
  double density = crop.contains(cv::Point(x, y)) ? 1.0 - fg - fe : 0.0;
  if (f.mask.at<unsigned char>(y, x) == kMaskObject) density += fg * n / n_object;
  if (in_boundary_[video][frame].at<unsigned char>(y, x) != 0) density += fe * n / n_edge;
  // An active ray jittered off the crop: weighed as if just inside it.
  if (density <= 0.0) density = 1.0 - fg - fe;
  return 1.0 / density;
}

void RaySampler::RecordErrors(const std::vector<Ray>& rays, const std::vector<double>& errors) {
  CHECK_EQ(rays.size(), errors.size());
  for (size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    error_cache_.push_back(
        {r.video, r.frame, static_cast<int>(r.uv[0]), static_cast<int>(r.uv[1]), errors[i]});
  }
  // Keep the most recent rays (oldest first).
  if (error_cache_.size() > kErrorWindow) {
    error_cache_.erase(error_cache_.begin(), error_cache_.end() - kErrorWindow);
  }
}

}  // namespace banmo
