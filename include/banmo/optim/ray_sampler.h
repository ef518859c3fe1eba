// Minibatches of pixel rays drawn from a dataset (docs/solver.md):
// a fresh random set per batch, part inside the object mask, part near its
// edge, part uniform over the image, part "active" (near pixels whose
// residuals were large in earlier batches), each with a random flow
// partner frame and stratified depth samples between the frame's near and
// far planes.
#pragma once

#include <Eigen/Geometry>
#include <random>
#include <utility>
#include <vector>

#include "banmo/io/dataset.h"
#include "banmo/losses/ray.h"
#include "banmo/model/model.h"
#include "banmo/optim/config.h"
#include "banmo/volume/ray_samples.h"

namespace banmo {

class RaySampler {
 public:
  // Indexes the object and mask-edge pixels of every usable frame (skipped
  // frames are never drawn).
  explicit RaySampler(const Dataset& dataset);

  // Half-width of the band sampling.boundary_fraction draws from: pixels
  // within this many pixels (chessboard distance) of a pixel of the other
  // class (object / background). The rendered silhouettes' errors sit
  // there: on the default scene 81 % of the wrong pixels of `banmo render`
  // lie within 1 px of the other mask, 97 % within 2.
  static constexpr int kBoundaryBandPx = 2;

  // Draws `count` rays with `samples_per_ray` depth samples each.
  std::vector<Ray> Sample(int count, int samples_per_ray, const SamplingConfig& sampling,
                          const Model& model, const Eigen::AlignedBox3d& canonical_bounds,
                          std::mt19937* rng) const;

  // Draws `count` rays of frame (video, frame) alone, no active rays (the
  // per-frame pose solves).
  std::vector<Ray> SampleFrame(int video, int frame, int count, int samples_per_ray,
                               const SamplingConfig& sampling, const Model& model,
                               const Eigen::AlignedBox3d& canonical_bounds,
                               std::mt19937* rng) const;

  // Importance weight of pixel (x, y) of frame (video, frame) drawn by the
  // sampler's mixture (`foreground_fraction` f inside the mask,
  // `boundary_fraction` e in the edge band, the rest uniform over the
  // frame's crop, CropRect): (1 / N) / p(pixel), N the crop's pixel count.
  // A ray's loss times this weight has the expectation of the same loss
  // over the crop's pixels drawn uniformly, and the weights of a frame's
  // draws average 1:
  //   1 / (f N / N_object [object] + e N / N_band [band] + (1 - f - e) [crop]).
  // Active rays take their pixel's weight too (an approximation: the
  // error cache's emphasis stays; one jittered off the crop and off the
  // band counts as inside the crop).
  double PixelWeight(int video, int frame, int x, int y, const SamplingConfig& sampling) const;

  // The pixels the uniform part of frame (video, frame)'s draws covers: the
  // whole image when sampling.crop_scale is 0 or the frame has no object
  // pixel, else the bounding box of its object pixels scaled by crop_scale
  // about its centre (each side), clipped to the image: the object then
  // takes the same share of the uniform draws however much of the frame it
  // fills, as in BANMo's object-centred crops.
  cv::Rect CropRect(int video, int frame, const SamplingConfig& sampling) const;

  // The frame's edge-band pixels (y * width + x, increasing).
  const std::vector<int>& BoundaryPixels(int video, int frame) const {
    return boundary_pixels_[video][frame];
  }

  // The usable (not skipped) frames, as (video, frame), in dataset order.
  std::vector<std::pair<int, int>> UsableFrames() const {
    std::vector<std::pair<int, int>> out;
    for (const FrameRef& f : frames_) out.emplace_back(f.video, f.frame);
    return out;
  }

  // Active sampling: remembers the rays of a batch with their errors; later
  // batches draw `sampling.active_fraction` of their rays next to them,
  // error-proportionally. The cache is a sliding window of the last
  // kErrorWindow rays (8 batches of 512), so it follows the current model:
  // errors of an early model (or of another stage) age out instead of
  // drawing rays forever.
  static constexpr size_t kErrorWindow = 4096;
  void RecordErrors(const std::vector<Ray>& rays, const std::vector<double>& errors);

  // The error cache, for checkpoints (resume must reproduce active sampling).
  struct CachedPixel {
    int video, frame, x, y;
    double error;
  };
  const std::vector<CachedPixel>& error_cache() const { return error_cache_; }
  void set_error_cache(std::vector<CachedPixel> cache) { error_cache_ = std::move(cache); }

 private:
  struct FrameRef {
    int video;
    int frame;
  };
  Ray MakeRay(int video, int frame, int x, int y, int samples_per_ray,
              const SamplingConfig& sampling, const Model& model,
              const Eigen::AlignedBox3d& canonical_bounds, std::mt19937* rng) const;
  Ray RandomRay(int video, int frame, int samples_per_ray, const SamplingConfig& sampling,
                const Model& model, const Eigen::AlignedBox3d& canonical_bounds,
                std::mt19937* rng) const;

  const Dataset& dataset_;
  std::vector<FrameRef> frames_;
  std::vector<std::vector<std::vector<int>>> object_pixels_;    // [video][frame] -> y * width + x
  std::vector<std::vector<std::vector<int>>> boundary_pixels_;  // the same, edge band
  std::vector<std::vector<cv::Mat>> in_boundary_;               // CV_8UC1, 1 on the band
  std::vector<std::vector<cv::Rect>> object_box_;               // bounding box of the object pixels
  std::vector<CachedPixel> error_cache_;
};

}  // namespace banmo
