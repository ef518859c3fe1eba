// Images of a model for one dataset frame, rendered by the training pipeline
// itself (`banmo render`, docs/render.md): every pixel becomes a Ray (losses/ray.h)
// carrying the observed colour and flow, RayBatch::EvaluateRays evaluates it
// exactly as the losses do (jacobians off), and with unit weights on the rgb,
// silhouette and flow terms the rendered values are
//   rendered colour  = observed rgb  + r_rgb   (RgbLoss: r = c - c_hat)
//   rendered opacity = ray mask      + r_sil   (SilhouetteLoss: r = o - s_hat)
//   rendered flow    = observed flow + r_flow  (FlowLoss: r = F - F_hat)
// so no second renderer exists to drift from the one the solver trains.
//
// Rays are built as optim/ray_sampler.cc builds them: pixel centre uv =
// (x + 0.5, y + 0.5), depth samples between the frame's near and far planes
// (volume/ray_samples.h, NearFarPlanes: canonical bounds through the root
// pose, +- margin), stratified in their bins (at the midpoints, or jittered
// and averaged over jitter_passes), optionally refined by the solver's
// importance resampling; every draw is seeded per pass and pixel, so a
// picture is the same every time. Every ray carries mask = 1 so the rgb
// and flow terms are active on every pixel (the losses switch them off on
// background pixels); the error maps compare with the real observations
// separately (ComputeErrorMaps).
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>

#include "banmo/extract/extract.h"
#include "banmo/io/dataset.h"
#include "banmo/model/model.h"

namespace banmo {

struct FrameRenderOptions {
  // Depth samples per ray (> 0). The solver's stage config has the value
  // the model was trained with (samples_per_ray).
  int samples_per_ray = 32;
  // Near/far planes: the canonical bounds' depth range through the root
  // pose, widened by this fraction (>= 0), as SamplingConfig::near_far_margin.
  double near_far_margin = 0.2;
  // Each ray clipped to the canonical box widened by clip_margin times its
  // largest side, as SamplingConfig::clip_to_box.
  bool clip_to_box = false;
  double clip_margin = 0.1;
  // Rays that miss RenderHitBox (below) widened by clip_margin times its
  // largest side (ClipDepthsToBox) are not evaluated: their pixels render
  // empty (rgb, opacity and flow 0). That box holds the surface and every
  // place the solver sampled, so what is lost is only density the training
  // rays never reached or the SDF leaves far from its surface; it saves the
  // rays of most of a real frame's pixels. false: every pixel's ray is
  // evaluated, as the losses evaluate every sampled ray.
  bool skip_rays_outside_box = true;
  // Canonical box whose depth range bounds the samples (non-empty);
  // CanonicalBoundsFromSurface (extract/extract.h) gives the solver's kind
  // of box.
  Eigen::AlignedBox3d canonical_bounds{Eigen::Vector3d::Constant(-1.2),
                                       Eigen::Vector3d::Constant(1.2)};
  // Second pass as the solver's importance_depth sampling: half of the
  // samples are redrawn from the first pass's rendering weights
  // (ImportanceResample, seeded from importance_seed, the jitter pass and
  // the pixel index, so the result is deterministic). About doubles the
  // cost (more with importance_samples).
  bool importance = false;
  uint32_t importance_seed = 0;
  // Samples the importance pass adds (ImportanceResample's `added`; >= 0):
  // 0 redraws half of samples_per_ray, K > 0 keeps them all and adds K, as
  // the solver's sampling.importance_samples.
  int importance_samples = 0;
  // With importance: one of the drawn samples goes to each ray's SDF
  // minimum instead, as the solver's sampling.min_sdf_sample.
  bool min_sdf_sample = false;
  // 0: the samples at their bins' midpoints (one deterministic pass). K > 0:
  // the mean of K passes whose samples are jittered within their bins as the
  // solver draws them (StratifiedSamples with jitter), seeded from
  // importance_seed, the pass and the pixel: an estimate of the expected
  // rendering the losses fit. K times the cost.
  int jitter_passes = 0;
  // Rays evaluated per call of RayBatch::EvaluateRays (> 0): bounds memory
  // (measured ~6 kB per sample of a ray: 1024 rays x 24 samples ~150 MB).
  int chunk_rays = 1024;
  // Gap of the rendered flow (> 0): partner frame t + gap, or t - gap when
  // t + gap is past the end of the video; no flow for one-frame videos.
  int flow_gap = 1;

  // Throws InputError naming the field on a violated constraint.
  void Check() const;
};

// The observations of one frame in the units of the losses (doubles).
struct ObservedFrame {
  int video = 0;
  int frame = 0;
  int partner_frame = -1;  // frame t' of the flow (see FrameRenderOptions::flow_gap), -1 = none
  cv::Mat rgb;             // CV_64FC3, RGB in [0, 1]
  cv::Mat mask;            // CV_64FC1: 1 object, 0 background, -1 unknown (kMaskIgnore)
  cv::Mat flow;            // CV_64FC2 observed flow t -> t' in pixels (0 where invalid)
  cv::Mat flow_valid;      // CV_8UC1: 255 where the dataset has valid flow t -> t'
};

// Reads frame (video, frame) of `dataset`; the flow is the dataset's flow for
// the partner's gap (flow_valid all 0 if the dataset has none).
ObservedFrame ObserveFrame(const Dataset& dataset, int video, int frame, int flow_gap);

// The model's images of a frame.
struct RenderedFrame {
  int video = 0;
  int frame = 0;
  int partner_frame = -1;  // as ObservedFrame
  cv::Mat rgb;             // CV_64FC3 sum_i tau_i c_i (Eq. 4), no background colour
  cv::Mat opacity;         // CV_64FC1 sum_i tau_i
  cv::Mat flow;            // CV_64FC2 expected displacement to t' (Eqs. 6-7), 0 if no partner
};

// The box of skip_rays_outside_box: the render's canonical_bounds extended
// by the box the solver sampled in when the model records it
// (Model::canonical_bounds). A model whose density is a fog around a small
// surface keeps its fog in the picture.
Eigen::AlignedBox3d RenderHitBox(const Model& model, const Eigen::AlignedBox3d& render_box);

// Renders every pixel of `observed`'s frame (image size = observed.rgb's).
// The model is only read (RayBatch needs a mutable pointer for Ceres; its
// EvaluateRays does not write). Uses ParallelFor inside the ray pipeline.
RenderedFrame RenderFrame(const Model& model, const ObservedFrame& observed,
                          const FrameRenderOptions& options);

// Per-pixel errors, NaN where the quantity is not defined.
struct ErrorMaps {
  cv::Mat rgb;   // CV_64FC1 mean over channels of |c - c_hat| on observed object pixels
  cv::Mat mask;  // CV_64FC1 |o - s_hat| where the mask is known
  cv::Mat flow;  // CV_64FC1 endpoint error |F - F_hat| (px) on object pixels with valid flow
};
ErrorMaps ComputeErrorMaps(const RenderedFrame& rendered, const ObservedFrame& observed);

// Means of the error maps and the silhouette IoU of one frame.
struct FrameErrors {
  double rgb = 0.0;       // mean of ErrorMaps::rgb (NaN if no object pixel)
  double mask = 0.0;      // mean of ErrorMaps::mask
  double flow = 0.0;      // mean endpoint error (NaN if no valid flow)
  double mask_iou = 0.0;  // IoU of {o >= 0.5} and {s_hat = 1} over known pixels (NaN if both empty)
  // PSNR (dB) of the rendered colour on the observed object pixels, colours
  // in [0, 1]: -10 log10(mean squared difference over pixels and channels);
  // NaN without object pixels.
  double psnr = 0.0;
  int rgb_pixels = 0, mask_pixels = 0, flow_pixels = 0;  // pixels averaged
};
FrameErrors SummarizeErrors(const ErrorMaps& errors, const RenderedFrame& rendered,
                            const ObservedFrame& observed);

// The sampling the model was trained with (Model::training_sampling: samples
// per ray, near/far margin, clipping, importance resampling); options
// unchanged for a model without it.
void SetTrainedSampling(const Model& model, FrameRenderOptions* options);

// Throws InputError naming `data_dir` if the dataset does not match the model:
// number of videos, frames per video, image size or camera intrinsics
// (relative difference > 1e-6) of a video.
void CheckDatasetMatchesModel(const Dataset& dataset, const Model& model,
                              const std::string& data_dir);

}  // namespace banmo
