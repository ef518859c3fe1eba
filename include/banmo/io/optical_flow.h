// Optical flow for real videos: OpenCV's DIS optical flow (Kroeger et al.,
// ECCV 2016) and occlusion from forward-backward consistency.
#pragma once

#include <opencv2/core.hpp>

namespace banmo {

enum class DisPreset {
  kMedium,  // cv::DISOpticalFlow::PRESET_MEDIUM (finest scale 1 = half resolution)
  kFine,    // PRESET_MEDIUM refined down to full resolution (finest scale 0)
};

struct OpticalFlowOptions {
  DisPreset preset = DisPreset::kMedium;  // DIS settings (kFine is slower, see docs/dataset.md)
  // Forward-backward consistency (Sundaram, Brox, Keutzer, ECCV 2010): the
  // flow at x is valid iff x + f(x) lies inside the image and
  //   |f(x) + b(x + f(x))|^2 < fb_alpha * (|f(x)|^2 + |b(x + f(x))|^2) + fb_beta,
  // with b the reverse flow sampled bilinearly.
  double fb_alpha = 0.01;  // relative tolerance (dimensionless)
  double fb_beta = 0.5;    // absolute tolerance in px^2 (0.71 px)

  // Throws InputError naming the field on a bad value.
  void Check() const;
};

// Dense flow from `from` to `to` (same size, CV_8UC3 RGB or CV_8UC1):
// CV_32FC2 (du, dv) in pixels, so pixel x of `from` moves to x + flow(x).
cv::Mat ComputeDisFlow(const cv::Mat& from, const cv::Mat& to, DisPreset preset);

// Validity of `forward` (from a to b) given `backward` (from b to a):
// CV_8UC1, 255 = consistent and inside the image, 0 = occluded/out of view.
cv::Mat ForwardBackwardValid(const cv::Mat& forward, const cv::Mat& backward,
                             const OpticalFlowOptions& options);

}  // namespace banmo
