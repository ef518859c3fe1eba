// Dataset PNGs (io/codecs.cc): the first byte selects RGB, mask, KITTI flow
// (decoded to flow and validity) or 16-bit depth; the rest is the file.
#include <opencv2/core.hpp>

#include "banmo/io/codecs.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string bytes = banmo::fuzz::AsString(data + 1, size - 1);
  banmo::fuzz::Expect([&] {
    switch (data[0] % 4) {
      case 0:
        banmo::DecodePngStrict(bytes, "rgb.png", CV_8U, 3, 0, 0);
        break;
      case 1:
        banmo::DecodePngStrict(bytes, "mask.png", CV_8U, 1, 0, 0);
        break;
      case 2: {
        const cv::Mat encoded = banmo::DecodePngStrict(bytes, "flow.png", CV_16U, 3, 0, 0);
        cv::Mat flow, valid;
        banmo::DecodeFlowKitti(encoded, "flow.png", &flow, &valid);
        break;
      }
      default:
        banmo::DecodePngStrict(bytes, "depth.png", CV_16U, 1, 0, 0);
    }
  });
  return 0;
}
