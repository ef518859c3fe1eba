#include "banmo/io/codecs.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "banmo/util/error.h"
#include "banmo/util/input_file.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

constexpr unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
constexpr unsigned char kPngIend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
constexpr std::size_t kPngHeadBytes = 8 + 8 + 13;  // signature + IHDR length/type + IHDR data

std::uint32_t ReadBigEndian32(const unsigned char* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) |
         std::uint32_t(p[3]);
}

const char* DepthName(int depth) {
  switch (depth) {
    case CV_8U:
      return "8-bit";
    case CV_16U:
      return "16-bit";
    default:
      return "?";
  }
}

void CheckInfo(const PngInfo& info, const std::string& name, int depth, int channels, int width,
               int height) {
  const int want_bits = depth == CV_16U ? 16 : 8;
  if (info.bit_depth != want_bits || info.channels != channels) {
    ThrowInputError(name, ": expected a ", DepthName(depth), " PNG with ", channels,
                    " channel(s), found ", info.bit_depth, "-bit with ", info.channels,
                    " channel(s)");
  }
  if (width > 0 && height > 0 && (info.width != width || info.height != height)) {
    ThrowInputError(name, ": image size ", info.width, "x", info.height, " does not match ", width,
                    "x", height, " (width x height of the video)");
  }
}

template <typename T>
bool AllFiniteTyped(const cv::Mat& m, cv::Vec3i* first_bad) {
  const int cn = m.channels();
  for (int r = 0; r < m.rows; ++r) {
    const T* row = m.ptr<T>(r);
    for (int i = 0; i < m.cols * cn; ++i) {
      if (!std::isfinite(static_cast<double>(row[i]))) {
        if (first_bad) *first_bad = cv::Vec3i(r, i / cn, i % cn);
        return false;
      }
    }
  }
  return true;
}

}  // namespace

std::string ReadFileBytes(const std::string& path) { return ReadRegularFile(path); }

PngInfo ParsePngInfo(const std::string& bytes, const std::string& name) {
  const auto* u = reinterpret_cast<const unsigned char*>(bytes.data());
  if (bytes.size() < kPngHeadBytes || std::memcmp(u, kPngSignature, 8) != 0) {
    ThrowInputError(name, ": not a PNG file (bad signature or shorter than its header)");
  }
  if (ReadBigEndian32(u + 8) != 13 || std::memcmp(u + 12, "IHDR", 4) != 0) {
    ThrowInputError(name, ": corrupt PNG (first chunk is not IHDR)");
  }
  PngInfo info;
  const std::uint32_t width = ReadBigEndian32(u + 16), height = ReadBigEndian32(u + 20);
  if (width == 0 || height == 0 || width > kMaxImageSide || height > kMaxImageSide ||
      static_cast<long>(width) * height > kMaxFramePixels) {
    ThrowInputError(name, ": PNG of ", width, "x", height, " pixels is beyond the limit (sides 1..",
                    kMaxImageSide, ", at most ", kMaxFramePixels, " pixels)");
  }
  info.width = static_cast<int>(width);
  info.height = static_cast<int>(height);
  info.bit_depth = u[24];
  switch (u[25]) {
    case 0:
      info.channels = 1;
      break;
    case 2:
    case 3:
      info.channels = 3;
      break;
    case 4:
      info.channels = 2;
      break;
    case 6:
      info.channels = 4;
      break;
    default:
      ThrowInputError(name, ": corrupt PNG (colour type ", int(u[25]), ")");
  }
  return info;
}

PngInfo CheckPngComplete(const std::string& bytes, const std::string& name) {
  const PngInfo info = ParsePngInfo(bytes, name);
  if (bytes.size() < kPngHeadBytes + 12 ||
      std::memcmp(bytes.data() + bytes.size() - 12, kPngIend, 12) != 0) {
    ThrowInputError(name, ": truncated PNG (the file does not end with an IEND chunk)");
  }
  return info;
}

cv::Mat DecodePngStrict(const std::string& bytes, const std::string& name, int depth, int channels,
                        int width, int height) {
  const PngInfo info = CheckPngComplete(bytes, name);
  CheckInfo(info, name, depth, channels, width, height);
  const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
  cv::Mat image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  if (image.empty()) ThrowInputError(name, ": unreadable PNG (decoding failed)");
  if (image.depth() != depth || image.channels() != channels) {
    ThrowInputError(name, ": expected a ", DepthName(depth), " PNG with ", channels,
                    " channel(s), decoded ", image.channels(), " channel(s) of depth ",
                    image.depth());
  }
  return image;
}

PngInfo CheckPngFile(const std::string& path, int depth, int channels, int width, int height) {
  CheckRegularFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInputError(path, ": cannot open file");
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  in.seekg(0);
  std::string head(kPngHeadBytes, '\0');
  if (size < static_cast<std::streamoff>(kPngHeadBytes + 12)) {
    ThrowInputError(path, ": not a PNG file (only ", size, " bytes)");
  }
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  const PngInfo info = ParsePngInfo(head, path);
  char tail[12];
  in.seekg(size - 12);
  in.read(tail, 12);
  if (!in || std::memcmp(tail, kPngIend, 12) != 0) {
    ThrowInputError(path, ": truncated PNG (the file does not end with an IEND chunk)");
  }
  CheckInfo(info, path, depth, channels, width, height);
  return info;
}

cv::Mat EncodeFlowKitti(const cv::Mat& flow, const cv::Mat& valid, int* num_clamped) {
  CHECK(flow.type() == CV_16FC2 || flow.type() == CV_32FC2) << "flow must be CV_16FC2/CV_32FC2";
  CHECK_EQ(valid.type(), CV_8UC1);
  CHECK(flow.size() == valid.size());
  cv::Mat flow32;
  flow.convertTo(flow32, CV_32F);
  cv::Mat out(flow.size(), CV_16UC3);
  int clamped = 0;
  const double lo = 0.0;
  const double hi = 65535.0;
  for (int r = 0; r < flow.rows; ++r) {
    const cv::Vec2f* f = flow32.ptr<cv::Vec2f>(r);
    const unsigned char* v = valid.ptr<unsigned char>(r);
    cv::Vec3w* o = out.ptr<cv::Vec3w>(r);
    for (int c = 0; c < flow.cols; ++c) {
      const double eu = std::round(f[c][0] * kKittiFlowScale + kKittiFlowOffset);
      const double ev = std::round(f[c][1] * kKittiFlowScale + kKittiFlowOffset);
      // NaN fails both comparisons below and is clamped to 0 (and marked invalid).
      const bool in_range = eu >= lo && eu <= hi && ev >= lo && ev <= hi;
      if (!in_range) ++clamped;
      const auto clamp = [&](double x) {
        return static_cast<std::uint16_t>(x >= lo ? (x <= hi ? x : hi) : lo);
      };
      // BGR order: B = valid, G = v, R = u.
      o[c] = cv::Vec3w(in_range && v[c] != 0 ? 1 : 0, clamp(ev), clamp(eu));
    }
  }
  if (num_clamped) *num_clamped = clamped;
  return out;
}

void DecodeFlowKitti(const cv::Mat& bgr16, const std::string& name, cv::Mat* flow, cv::Mat* valid) {
  CHECK_EQ(bgr16.type(), CV_16UC3);
  flow->create(bgr16.size(), CV_32FC2);
  valid->create(bgr16.size(), CV_8UC1);
  for (int r = 0; r < bgr16.rows; ++r) {
    const cv::Vec3w* in = bgr16.ptr<cv::Vec3w>(r);
    cv::Vec2f* f = flow->ptr<cv::Vec2f>(r);
    unsigned char* v = valid->ptr<unsigned char>(r);
    for (int c = 0; c < bgr16.cols; ++c) {
      if (in[c][0] > 1) {
        ThrowInputError(name, ": flow valid channel (blue) must be 0 or 1, found ", in[c][0],
                        " at pixel (x=", c, ", y=", r, ")");
      }
      v[c] = in[c][0] ? 255 : 0;
      f[c][0] = static_cast<float>((in[c][2] - kKittiFlowOffset) / kKittiFlowScale);
      f[c][1] = static_cast<float>((in[c][1] - kKittiFlowOffset) / kKittiFlowScale);
    }
  }
}

bool AllFinite(const cv::Mat& m, cv::Vec3i* first_bad) {
  switch (m.depth()) {
    case CV_16F: {
      // Half floats: non-finite iff all exponent bits are set.
      const int cn = m.channels();
      for (int r = 0; r < m.rows; ++r) {
        const std::uint16_t* row = m.ptr<std::uint16_t>(r);
        for (int i = 0; i < m.cols * cn; ++i) {
          if ((row[i] & 0x7c00u) == 0x7c00u) {
            if (first_bad) *first_bad = cv::Vec3i(r, i / cn, i % cn);
            return false;
          }
        }
      }
      return true;
    }
    case CV_32F:
      return AllFiniteTyped<float>(m, first_bad);
    case CV_64F:
      return AllFiniteTyped<double>(m, first_bad);
    default:
      return true;  // integer types are always finite
  }
}

}  // namespace banmo
