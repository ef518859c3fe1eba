// The pictures of `banmo render` (docs/render.md): 8-bit RGB panels (channel
// order R, G, B like the dataset; convert to BGR only when writing with
// OpenCV), each the size of the input image times an integer scale.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "banmo/geometry/camera.h"
#include "banmo/geometry/mesh.h"

namespace banmo {

// Colours of the mask-agreement panel (RGB).
inline const cv::Vec3b kMaskBothColor(255, 255, 255);        // rendered and input object
inline const cv::Vec3b kMaskRenderedOnlyColor(230, 50, 50);  // rendered only (red)
inline const cv::Vec3b kMaskInputOnlyColor(40, 140, 255);    // input only (blue)
inline const cv::Vec3b kMaskNeitherColor(0, 0, 0);           // background in both
inline const cv::Vec3b kMaskUnknownColor(70, 70, 70);        // input mask unknown (ignore)
// Error maps: pixels where the error is not defined (NaN).
inline const cv::Vec3b kErrorUndefinedColor(128, 128, 128);

// Colour image in [0, 1] (CV_64FC3, RGB) to CV_8UC3, clamped and rounded.
cv::Mat ToRgb8(const cv::Mat& rgb);

// Mask agreement: with rendered object = opacity >= threshold and input
// object = mask >= 0.5 (mask < 0 = unknown), each pixel gets one of the
// kMask*Color colours above.
cv::Mat MaskAgreementImage(const cv::Mat& opacity, const cv::Mat& mask, double threshold = 0.5);

// Error map (CV_64FC1, NaN = undefined) through OpenCV's INFERNO colormap
// over [0, max_value] (values above max_value saturate; black = 0, pale
// yellow = max_value); NaN pixels get kErrorUndefinedColor.
cv::Mat ColorizeError(const cv::Mat& error, double max_value);

// Lambert shading of a mesh given in camera coordinates, seen by `camera`
// (banmo::synth::Rasterize), lit by a headlight at the camera centre:
//   colour = base * (ambient + (1 - ambient) * |n . l|),
// n the interpolated vertex normal (area-weighted face normals), l the unit
// direction from the surface point to the camera; |.| so back faces are lit
// alike (the rasteriser does no culling). base = the mesh's interpolated
// vertex colours when use_vertex_colors and the mesh has them, else
// `base_color`. Background black.
struct ShadeOptions {
  double ambient = 0.2;                             // in [0, 1]
  cv::Vec3b base_color = cv::Vec3b(200, 200, 200);  // RGB, when vertex colours are not used
  bool use_vertex_colors = false;
};
cv::Mat ShadeMesh(const TriangleMesh& mesh_in_camera, const PinholeCamera& camera,
                  const ShadeOptions& options = {});

// Writes `text` in the top-left corner (white with a black outline), the
// font scaled to the panel width.
void DrawLabel(cv::Mat* panel, const std::string& text);

// Nearest-neighbour upscale by an integer factor (>= 1).
cv::Mat UpscalePanel(const cv::Mat& panel, int scale);

// Panels side by side (all CV_8UC3 of one size).
cv::Mat ConcatPanels(const std::vector<cv::Mat>& panels);

// PNG bytes of an RGB image (converted to OpenCV's BGR order).
std::string EncodePng(const cv::Mat& rgb8);

}  // namespace banmo
