#include "banmo/io/optical_flow.h"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

void OpticalFlowOptions::Check() const {
  if (!(std::isfinite(fb_alpha) && fb_alpha >= 0)) {
    ThrowInputError("OpticalFlowOptions::fb_alpha = ", fb_alpha, ", expected >= 0");
  }
  if (!(std::isfinite(fb_beta) && fb_beta >= 0)) {
    ThrowInputError("OpticalFlowOptions::fb_beta = ", fb_beta, ", expected >= 0");
  }
}

cv::Mat ComputeDisFlow(const cv::Mat& from, const cv::Mat& to, DisPreset preset) {
  CHECK(from.size() == to.size() && from.type() == to.type());
  CHECK(from.type() == CV_8UC3 || from.type() == CV_8UC1);
  cv::Mat a = from;
  cv::Mat b = to;
  if (from.channels() == 3) {
    cv::cvtColor(from, a, cv::COLOR_RGB2GRAY);
    cv::cvtColor(to, b, cv::COLOR_RGB2GRAY);
  }
  cv::Ptr<cv::DISOpticalFlow> dis = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
  if (preset == DisPreset::kFine) dis->setFinestScale(0);
  cv::Mat flow;
  dis->calc(a, b, flow);
  CHECK_EQ(flow.type(), CV_32FC2);
  return flow;
}

cv::Mat ForwardBackwardValid(const cv::Mat& forward, const cv::Mat& backward,
                             const OpticalFlowOptions& options) {
  CHECK_EQ(forward.type(), CV_32FC2);
  CHECK_EQ(backward.type(), CV_32FC2);
  CHECK(forward.size() == backward.size());
  const int w = forward.cols;
  const int h = forward.rows;
  // b(x + f(x)) by bilinear sampling.
  cv::Mat map(forward.size(), CV_32FC2);
  for (int y = 0; y < h; ++y) {
    const cv::Vec2f* f = forward.ptr<cv::Vec2f>(y);
    cv::Vec2f* m = map.ptr<cv::Vec2f>(y);
    for (int x = 0; x < w; ++x) m[x] = cv::Vec2f(x + f[x][0], y + f[x][1]);
  }
  cv::Mat back_at_target;
  cv::remap(backward, back_at_target, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::Mat valid(forward.size(), CV_8UC1);
  for (int y = 0; y < h; ++y) {
    const cv::Vec2f* f = forward.ptr<cv::Vec2f>(y);
    const cv::Vec2f* b = back_at_target.ptr<cv::Vec2f>(y);
    const cv::Vec2f* m = map.ptr<cv::Vec2f>(y);
    unsigned char* v = valid.ptr<unsigned char>(y);
    for (int x = 0; x < w; ++x) {
      // Pixel index coordinates: the image covers [-0.5, w - 0.5).
      const bool inside =
          m[x][0] >= -0.5f && m[x][0] < w - 0.5f && m[x][1] >= -0.5f && m[x][1] < h - 0.5f;
      const double su = f[x][0] + b[x][0];
      const double sv = f[x][1] + b[x][1];
      const double lhs = su * su + sv * sv;
      const double rhs = options.fb_alpha * (f[x].dot(f[x]) + b[x].dot(b[x])) + options.fb_beta;
      v[x] = inside && lhs < rhs ? 255 : 0;
    }
  }
  return valid;
}

}  // namespace banmo
