#include "banmo/visualize/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "banmo/extract/extract.h"
#include "banmo/geometry/box.h"
#include "banmo/losses/ray_batch.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/volume/ray_samples.h"

namespace banmo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The loss weights of a render: unit weights on the three terms whose
// residuals give rendered values, everything else off.
RayBatchOptions RenderBatchOptions() {
  RayBatchOptions o;
  o.weights = RayLossWeights::Only({LossTerm::kRgb, LossTerm::kSilhouette, LossTerm::kFlow});
  return o;
}

int PartnerFrame(int frame, int num_frames, int gap) {
  if (frame + gap < num_frames) return frame + gap;
  if (frame - gap >= 0) return frame - gap;
  return -1;
}

}  // namespace

Eigen::AlignedBox3d RenderHitBox(const Model& model, const Eigen::AlignedBox3d& render_box) {
  Eigen::AlignedBox3d box = render_box;
  if (model.canonical_bounds()) box.extend(*model.canonical_bounds());
  return box;
}

void FrameRenderOptions::Check() const {
  if (samples_per_ray <= 0) ThrowInputError("samples_per_ray: expected > 0, got ", samples_per_ray);
  if (!(near_far_margin >= 0.0)) {
    ThrowInputError("near_far_margin: expected >= 0, got ", near_far_margin);
  }
  if (!(clip_margin >= 0.0)) ThrowInputError("clip_margin: expected >= 0, got ", clip_margin);
  if (!IsValidBox(canonical_bounds)) {
    ThrowInputError("canonical_bounds: expected a finite box with max > min on every axis");
  }
  if (chunk_rays <= 0) ThrowInputError("chunk_rays: expected > 0, got ", chunk_rays);
  if (flow_gap <= 0) ThrowInputError("flow_gap: expected > 0, got ", flow_gap);
  if (jitter_passes < 0) ThrowInputError("jitter_passes: expected >= 0, got ", jitter_passes);
  if (importance_samples < 0) {
    ThrowInputError("importance_samples: expected >= 0, got ", importance_samples);
  }
}

ObservedFrame ObserveFrame(const Dataset& dataset, int video, int frame, int flow_gap) {
  CHECK_GE(video, 0);
  CHECK_LT(video, static_cast<int>(dataset.videos.size()));
  const Video& v = dataset.videos[video];
  CHECK_GE(frame, 0);
  CHECK_LT(frame, static_cast<int>(v.frames.size()));
  const Frame& f = v.frames[frame];
  ObservedFrame o;
  o.video = video;
  o.frame = frame;
  o.partner_frame = PartnerFrame(frame, static_cast<int>(v.frames.size()), flow_gap);
  f.rgb.convertTo(o.rgb, CV_64FC3, 1.0 / 255.0);
  o.mask.create(f.mask.size(), CV_64FC1);
  for (int y = 0; y < f.mask.rows; ++y) {
    for (int x = 0; x < f.mask.cols; ++x) {
      const unsigned char m = f.mask.at<unsigned char>(y, x);
      o.mask.at<double>(y, x) = m == kMaskObject ? 1.0 : (m == kMaskBackground ? 0.0 : -1.0);
    }
  }
  o.flow = cv::Mat::zeros(f.mask.size(), CV_64FC2);
  o.flow_valid = cv::Mat::zeros(f.mask.size(), CV_8UC1);
  if (o.partner_frame >= 0) {
    const FlowField* flow = f.FlowForGap(o.partner_frame - frame);
    if (flow != nullptr) {
      for (int y = 0; y < f.mask.rows; ++y) {
        for (int x = 0; x < f.mask.cols; ++x) {
          if (flow->valid.at<unsigned char>(y, x) == 0) continue;
          const cv::Vec<cv::float16_t, 2> d = flow->flow.at<cv::Vec<cv::float16_t, 2>>(y, x);
          o.flow.at<cv::Vec2d>(y, x) =
              cv::Vec2d(static_cast<float>(d[0]), static_cast<float>(d[1]));
          o.flow_valid.at<unsigned char>(y, x) = 255;
        }
      }
    }
  }
  return o;
}

RenderedFrame RenderFrame(const Model& model, const ObservedFrame& observed,
                          const FrameRenderOptions& options) {
  options.Check();
  const int width = observed.rgb.cols, height = observed.rgb.rows;
  CHECK_GT(width, 0);
  CHECK_EQ(observed.mask.cols, width);
  CHECK_EQ(observed.flow.cols, width);
  RayBatch batch(model, RenderBatchOptions());  // evaluation only
  const RayLossWeights& weights = batch.options().weights;

  RenderedFrame out;
  out.video = observed.video;
  out.frame = observed.frame;
  out.partner_frame = observed.partner_frame;
  out.rgb = cv::Mat::zeros(height, width, CV_64FC3);
  out.opacity = cv::Mat::zeros(height, width, CV_64FC1);
  out.flow = cv::Mat::zeros(height, width, CV_64FC2);

  double near, far;
  const Pose camera_from_root = model.RootPose(observed.video, observed.frame);
  NearFarPlanes(camera_from_root, options.canonical_bounds, options.near_far_margin, &near, &far);
  const Eigen::Vector4d& k = model.video(observed.video).intrinsics;

  const int num_pixels = width * height;
  // jitter_passes == 0: one pass at the bins' midpoints; K > 0: the mean of
  // K passes with jittered depths, each seeded per pass and pixel.
  const int passes = std::max(1, options.jitter_passes);
  const double pass_weight = 1.0 / passes;
  auto pixel_seed = [&](int pass, int pixel) {
    return options.importance_seed +
           static_cast<uint32_t>(pass) * static_cast<uint32_t>(num_pixels) +
           static_cast<uint32_t>(pixel);
  };
  // The pixels whose rays are evaluated, with their [near, far] (clipped to
  // the box with clip_to_box). A ray is skipped when it misses both the
  // render's box and the box the solver sampled in (RenderHitBox).
  const Eigen::AlignedBox3d hit_box = RenderHitBox(model, options.canonical_bounds);
  std::vector<int> pixels;
  std::vector<Eigen::Vector2d> pixel_ranges;
  pixels.reserve(num_pixels);
  pixel_ranges.reserve(num_pixels);
  for (int p = 0; p < num_pixels; ++p) {
    const Eigen::Vector2d uv((p % width) + 0.5, (p / width) + 0.5);
    if (options.skip_rays_outside_box) {
      double n = near, f = far;
      if (!ClipDepthsToBox(camera_from_root, hit_box, options.clip_margin, k, uv, &n, &f)) continue;
    }
    Eigen::Vector2d range(near, far);
    if (options.clip_to_box) {
      ClipDepthsToBox(camera_from_root, options.canonical_bounds, options.clip_margin, k, uv,
                      &range[0], &range[1]);
    }
    pixels.push_back(p);
    pixel_ranges.push_back(range);
  }
  const int num_rays = static_cast<int>(pixels.size());
  std::vector<Ray> rays;
  std::vector<const Ray*> ray_ptrs;
  std::vector<RayParameters> params;
  std::vector<RayEvaluation> evals;
  for (int begin = 0; begin < num_rays; begin += options.chunk_rays) {
    const int end = std::min(num_rays, begin + options.chunk_rays);
    // The chunk's rays once: what changes between passes is only their samples.
    rays.assign(end - begin, Ray());
    for (int i = begin; i < end; ++i) {
      const int p = pixels[i];
      const int x = p % width, y = p / width;
      Ray& ray = rays[i - begin];
      ray.video = observed.video;
      ray.frame = observed.frame;
      ray.uv = Eigen::Vector2d(x + 0.5, y + 0.5);
      const cv::Vec3d c = observed.rgb.at<cv::Vec3d>(y, x);
      ray.rgb = Eigen::Vector3d(c[0], c[1], c[2]);
      if (observed.partner_frame >= 0) {
        const cv::Vec2d f = observed.flow.at<cv::Vec2d>(y, x);
        ray.flow = Eigen::Vector2d(f[0], f[1]);
      }
    }
    ray_ptrs.resize(rays.size());
    params.resize(rays.size());
    for (size_t r = 0; r < rays.size(); ++r) ray_ptrs[r] = &rays[r];
    for (int pass = 0; pass < passes; ++pass) {
      for (size_t r = 0; r < rays.size(); ++r) {
        Ray& ray = rays[r];
        // The silhouette term only until the final evaluation: no colour MLP,
        // no flow partner in the importance pass.
        ray.mask = 0.0;
        ray.partner_frame = -1;
        ray.has_flow = false;
        const Eigen::Vector2d& range = pixel_ranges[begin + r];
        const double dir_norm = RayDirectionLength(k, ray.uv);
        if (options.jitter_passes > 0) {
          // Offset: a stream apart from the same pixel's importance draws.
          std::mt19937 jitter_rng(pixel_seed(pass, pixels[begin + r]) + 0x9e3779b9u);
          ray.samples = StratifiedSamples(options.samples_per_ray, range[0], range[1], dir_norm,
                                          true, &jitter_rng);
        } else {
          ray.samples = StratifiedSamples(options.samples_per_ray, range[0], range[1], dir_norm,
                                          false, nullptr);
        }
      }
      if (options.importance) {
        // First pass for the weights tau_i only.
        for (size_t r = 0; r < rays.size(); ++r) params[r] = batch.ModelParameters(rays[r]);
        batch.EvaluateRays(ray_ptrs, params, false, &evals);
        for (size_t r = 0; r < rays.size(); ++r) {
          std::mt19937 rng(pixel_seed(pass, pixels[begin + r]));
          ImportanceResample(evals[r].tau, options.importance_samples, &rays[r].samples, &rng,
                             options.min_sdf_sample ? &evals[r].sdf : nullptr);
        }
      }
      for (Ray& ray : rays) {
        ray.mask = 1.0;  // every term on (see the header)
        if (observed.partner_frame >= 0) {
          ray.partner_frame = observed.partner_frame;
          ray.has_flow = true;
        }
      }
      for (size_t r = 0; r < rays.size(); ++r) params[r] = batch.ModelParameters(rays[r]);
      batch.EvaluateRays(ray_ptrs, params, false, &evals);
      for (size_t r = 0; r < rays.size(); ++r) {
        const int p = pixels[begin + r];
        const int x = p % width, y = p / width;
        const Ray& ray = rays[r];
        const RayEvaluation& ev = evals[r];
        // Unit weights: rendered = observed + residual (header).
        const int rgb_row = ev.term_row[static_cast<int>(LossTerm::kRgb)];
        const int sil_row = ev.term_row[static_cast<int>(LossTerm::kSilhouette)];
        CHECK_GE(rgb_row, 0);
        CHECK_GE(sil_row, 0);
        out.rgb.at<cv::Vec3d>(y, x) +=
            pass_weight * cv::Vec3d(ray.rgb[0] + ev.residuals[rgb_row],
                                    ray.rgb[1] + ev.residuals[rgb_row + 1],
                                    ray.rgb[2] + ev.residuals[rgb_row + 2]);
        out.opacity.at<double>(y, x) += pass_weight * (ray.mask + ev.residuals[sil_row]);
        if (ray.HasTerm(LossTerm::kFlow, weights)) {
          const int flow_row = ev.term_row[static_cast<int>(LossTerm::kFlow)];
          CHECK_GE(flow_row, 0);
          out.flow.at<cv::Vec2d>(y, x) +=
              pass_weight * cv::Vec2d(ray.flow[0] + ev.residuals[flow_row],
                                      ray.flow[1] + ev.residuals[flow_row + 1]);
        }
      }
    }
  }
  return out;
}

ErrorMaps ComputeErrorMaps(const RenderedFrame& rendered, const ObservedFrame& observed) {
  const int width = observed.rgb.cols, height = observed.rgb.rows;
  CHECK_EQ(rendered.rgb.cols, width);
  CHECK_EQ(rendered.rgb.rows, height);
  ErrorMaps e;
  e.rgb = cv::Mat(height, width, CV_64FC1, cv::Scalar(kNaN));
  e.mask = cv::Mat(height, width, CV_64FC1, cv::Scalar(kNaN));
  e.flow = cv::Mat(height, width, CV_64FC1, cv::Scalar(kNaN));
  const bool has_flow = rendered.partner_frame >= 0 && !observed.flow_valid.empty();
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double s = observed.mask.at<double>(y, x);
      if (s >= 0.0) e.mask.at<double>(y, x) = std::abs(rendered.opacity.at<double>(y, x) - s);
      if (s < 0.5) continue;  // rgb and flow: object pixels only, as the losses
      const cv::Vec3d dc = rendered.rgb.at<cv::Vec3d>(y, x) - observed.rgb.at<cv::Vec3d>(y, x);
      e.rgb.at<double>(y, x) = (std::abs(dc[0]) + std::abs(dc[1]) + std::abs(dc[2])) / 3.0;
      if (has_flow && observed.flow_valid.at<unsigned char>(y, x) != 0) {
        const cv::Vec2d df = rendered.flow.at<cv::Vec2d>(y, x) - observed.flow.at<cv::Vec2d>(y, x);
        e.flow.at<double>(y, x) = std::hypot(df[0], df[1]);
      }
    }
  }
  return e;
}

FrameErrors SummarizeErrors(const ErrorMaps& errors, const RenderedFrame& rendered,
                            const ObservedFrame& observed) {
  FrameErrors s;
  double sum[3] = {0, 0, 0};
  double squared = 0.0;  // sum of squared colour differences over object pixels
  int inter = 0, uni = 0;
  for (int y = 0; y < errors.rgb.rows; ++y) {
    for (int x = 0; x < errors.rgb.cols; ++x) {
      const double e[3] = {errors.rgb.at<double>(y, x), errors.mask.at<double>(y, x),
                           errors.flow.at<double>(y, x)};
      int* counts[3] = {&s.rgb_pixels, &s.mask_pixels, &s.flow_pixels};
      for (int k = 0; k < 3; ++k) {
        if (std::isnan(e[k])) continue;
        sum[k] += e[k];
        ++*counts[k];
      }
      const double m = observed.mask.at<double>(y, x);
      if (m >= 0.5) {
        const cv::Vec3d dc = rendered.rgb.at<cv::Vec3d>(y, x) - observed.rgb.at<cv::Vec3d>(y, x);
        squared += dc.dot(dc);
      }
      if (m < 0.0) continue;
      const bool a = rendered.opacity.at<double>(y, x) >= 0.5, b = m >= 0.5;
      inter += a && b;
      uni += a || b;
    }
  }
  s.rgb = s.rgb_pixels > 0 ? sum[0] / s.rgb_pixels : kNaN;
  s.mask = s.mask_pixels > 0 ? sum[1] / s.mask_pixels : kNaN;
  s.flow = s.flow_pixels > 0 ? sum[2] / s.flow_pixels : kNaN;
  s.mask_iou = uni > 0 ? static_cast<double>(inter) / uni : kNaN;
  // Colours in [0, 1], so the peak signal is 1; a perfect match gives +inf.
  s.psnr = s.rgb_pixels > 0 ? -10.0 * std::log10(squared / (3.0 * s.rgb_pixels)) : kNaN;
  return s;
}

void SetTrainedSampling(const Model& model, FrameRenderOptions* options) {
  if (!model.training_sampling()) return;
  const TrainingSampling& trained = *model.training_sampling();
  options->samples_per_ray = trained.samples_per_ray;
  options->near_far_margin = trained.near_far_margin;
  options->clip_to_box = trained.clip_to_box;
  options->clip_margin = trained.clip_margin;
  options->importance = trained.importance_depth;
  options->importance_samples = trained.importance_samples;
  options->min_sdf_sample = trained.importance_depth && trained.min_sdf_sample;
}

void CheckDatasetMatchesModel(const Dataset& dataset, const Model& model,
                              const std::string& data_dir) {
  const int nv = static_cast<int>(dataset.videos.size());
  if (nv != model.num_videos()) {
    ThrowInputError(data_dir, ": the dataset has ", nv, " videos, the model ", model.num_videos(),
                    " (not the dataset the model was trained on?)");
  }
  for (int v = 0; v < nv; ++v) {
    const Video& video = dataset.videos[v];
    const VideoParameters& mv = model.video(v);
    const std::string where = data_dir + "/" + video.name;
    if (video.frames.size() != mv.frames.size()) {
      ThrowInputError(where, ": ", video.frames.size(), " frames, the model's video ", v, " has ",
                      mv.frames.size());
    }
    if (video.camera.width != mv.camera.width || video.camera.height != mv.camera.height) {
      ThrowInputError(where, ": images are ", video.camera.width, "x", video.camera.height,
                      ", the model's video ", v, " was ", mv.camera.width, "x", mv.camera.height);
    }
    const Eigen::Vector4d& a = video.camera.intrinsics;
    const Eigen::Vector4d& b = mv.camera.intrinsics;
    if ((a - b).cwiseAbs().maxCoeff() > 1e-6 * std::max(1.0, b.cwiseAbs().maxCoeff())) {
      ThrowInputError(where, ": intrinsics [", a.transpose(), "] differ from the model's video ", v,
                      " [", b.transpose(), "]");
    }
  }
}

}  // namespace banmo
