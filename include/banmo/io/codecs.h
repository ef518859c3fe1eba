// Image codecs of the dataset format (docs/dataset.md): strict PNG reading,
// KITTI-style 16-bit flow PNGs, 16-bit depth PNGs, finiteness checks.
#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace banmo {

// Image size limits of the dataset format (docs/robustness.md), checked
// before anything is allocated: a side of at most 16384 px, at most 2^25
// pixels (32 Mpx, e.g. 8192 x 4096) per frame, and at most 2^28 pixels over
// every frame of a dataset (~20 GB loaded with features and four flow gaps).
inline constexpr int kMaxImageSide = 16384;
inline constexpr long kMaxFramePixels = 1L << 25;
inline constexpr long kMaxDatasetPixels = 1L << 28;

// Whole file as bytes; throws InputError naming the path if it cannot be read.
std::string ReadFileBytes(const std::string& path);

// Width, height, bit depth and colour type from a PNG's IHDR chunk, without
// decoding. Throws InputError naming `name` if `bytes` is not a PNG or its
// size is beyond kMaxImageSide / kMaxFramePixels.
struct PngInfo {
  int width = 0;
  int height = 0;
  int bit_depth = 0;  // 8 or 16 (1, 2, 4 for palette/grey images)
  int channels = 0;   // 1 (grey), 2 (grey+alpha), 3 (RGB), 4 (RGBA); palette = 3
};
PngInfo ParsePngInfo(const std::string& bytes, const std::string& name);

// Checks that a PNG is complete: signature, IHDR and a final IEND chunk (so
// a truncated file is caught even where the decoder would silently return a
// partial image). Returns the IHDR info.
PngInfo CheckPngComplete(const std::string& bytes, const std::string& name);

// Decodes a complete PNG with cv::IMREAD_UNCHANGED and checks it has
// `channels` channels of depth `depth` (CV_8U or CV_16U) and, if width/height
// are positive, that size. Throws InputError naming `name` and what was
// expected. Channel order is OpenCV's (BGR).
cv::Mat DecodePngStrict(const std::string& bytes, const std::string& name, int depth, int channels,
                        int width = 0, int height = 0);

// Header-only version of the same checks (reads the file, does not decode).
PngInfo CheckPngFile(const std::string& path, int depth, int channels, int width = 0,
                     int height = 0);

// KITTI flow encoding: a 16-bit 3-channel PNG with R = u * 64 + 2^15,
// G = v * 64 + 2^15, B = valid (0 or 1). Range [-512, 512) px, step 1/64 px.
// Flow values outside the range are clamped and marked invalid.
inline constexpr double kKittiFlowScale = 64.0;
inline constexpr double kKittiFlowOffset = 32768.0;
// flow: CV_16FC2 or CV_32FC2; valid: CV_8UC1 (0 or 255). Returns the CV_16UC3
// image in OpenCV's BGR order, ready for cv::imwrite. *num_clamped (optional)
// receives the number of pixels out of range.
cv::Mat EncodeFlowKitti(const cv::Mat& flow, const cv::Mat& valid, int* num_clamped = nullptr);
// Inverse: flow CV_32FC2 and valid CV_8UC1 (0 or 255). Throws InputError
// naming `name` if the valid channel holds anything but 0 or 1.
void DecodeFlowKitti(const cv::Mat& bgr16, const std::string& name, cv::Mat* flow, cv::Mat* valid);

// True if every element of a CV_16F, CV_32F or CV_64F matrix is finite.
// On false, *first_bad (optional) receives (row, col, channel) of the first
// non-finite element in row-major order.
bool AllFinite(const cv::Mat& m, cv::Vec3i* first_bad = nullptr);

}  // namespace banmo
