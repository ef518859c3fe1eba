// Minibatches of pixel rays drawn from a dataset (docs/solver.md):
// a fresh random set per batch, part inside the object mask, part uniform
// over the image, part "active" (near pixels whose residuals were large in
// earlier batches), each with a random flow partner frame and stratified
// depth samples between the frame's near and far planes.
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
  // Indexes the object pixels of every usable frame (skipped frames are
  // never drawn).
  explicit RaySampler(const Dataset& dataset);

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

  // Importance weight of a pixel of frame (video, frame) drawn by the
  // sampler's mixture (`foreground_fraction` inside the mask, the rest
  // uniform over the image): (1 / N) / p(pixel), N the frame's pixel count.
  // A ray's loss times this weight has the expectation of the same loss
  // over pixels drawn uniformly, and the weights of a frame's draws average
  // 1. Object pixels: 1 / (f N / N_object + 1 - f); others: 1 / (1 - f).
  // Active rays take their pixel's weight too (an approximation: the
  // error cache's emphasis stays).
  double PixelWeight(int video, int frame, bool object, const SamplingConfig& sampling) const;

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
  std::vector<std::vector<std::vector<int>>> object_pixels_;  // [video][frame] -> y * width + x
  std::vector<CachedPixel> error_cache_;
};

}  // namespace banmo
