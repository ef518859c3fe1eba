// A small, strict reader and writer for NumPy .npy files (format 1.0, C order,
// little endian), used for the 16-channel pixel features and, optionally, for
// flow and depth. Only the dtypes below are supported:
//   '|u1' (CV_8U), '<u2' (CV_16U), '<f2' (CV_16F), '<f4' (CV_32F), '<f8' (CV_64F).
// Images are 2-D arrays (H, W) or 3-D arrays (H, W, C) with C channels
// interleaved, i.e. exactly the memory layout of a continuous cv::Mat.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace banmo {

// The parsed header of an .npy file.
struct NpyHeader {
  int major_version = 1;       // 1 or 2 (2 only differs in a 4-byte header length)
  std::string descr;           // dtype, e.g. "<f2"
  bool fortran_order = false;  // always false here (Fortran order is rejected)
  std::vector<std::int64_t> shape;
  std::size_t data_offset = 0;  // bytes before the array data (magic + header)

  // Bytes per element of descr (1, 2, 4 or 8).
  int ItemSize() const;
  // Product of shape times ItemSize() (1 element for a 0-d array).
  std::size_t DataBytes() const;
};

// Parses and checks the header at the start of `bytes` (at least the whole
// header must be there). Throws InputError naming `name` on: wrong magic,
// unsupported version, header length beyond the data, a header that is not a
// Python dict literal with exactly the keys 'descr', 'fortran_order' and
// 'shape', an unsupported or big-endian dtype, fortran_order True, negative
// or overflowing dimensions.
NpyHeader ParseNpyHeader(const std::string& bytes, const std::string& name);

// Reads only the header of the file at `path` and checks that the file size is
// exactly data_offset + DataBytes() (no truncation, no trailing bytes).
NpyHeader ReadNpyHeader(const std::string& path);

// Encodes a continuous 2-D cv::Mat as .npy bytes (format 1.0): shape (H, W)
// when it has one channel and !channel_axis, otherwise (H, W, C).
std::string EncodeNpy(const cv::Mat& image, bool channel_axis = true);

// Decodes .npy bytes holding a 2-D or 3-D array into a cv::Mat of H x W with C
// channels (C = 1 for 2-D arrays, at most CV_CN_MAX). All header checks of
// ParseNpyHeader, plus: the data size must match the shape exactly.
cv::Mat DecodeNpy(const std::string& bytes, const std::string& name);

// File versions; WriteNpy writes atomically (util/atomic_file.h).
cv::Mat ReadNpy(const std::string& path);
void WriteNpy(const std::string& path, const cv::Mat& image, bool channel_axis = true);

}  // namespace banmo
