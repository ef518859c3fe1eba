// io/optical_flow.h: DIS flow and the forward-backward consistency check.
#include "banmo/io/optical_flow.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "banmo/util/error.h"

namespace banmo {
namespace {

cv::Mat ConstantFlow(int h, int w, float u, float v) {
  return cv::Mat(h, w, CV_32FC2, cv::Scalar(u, v));
}

TEST(ForwardBackwardValid, ConsistentFlowIsValidWhereItLandsInTheImage) {
  const int h = 10, w = 12;
  const cv::Mat valid =
      ForwardBackwardValid(ConstantFlow(h, w, 3, -2), ConstantFlow(h, w, -3, 2), {});
  ASSERT_EQ(valid.type(), CV_8UC1);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // Lands on (x + 3, y - 2): inside for x < w - 3 and y >= 2.
      const bool inside = x + 3 < w && y - 2 >= 0;
      EXPECT_EQ(valid.at<uchar>(y, x), inside ? 255 : 0) << x << "," << y;
    }
  }
}

TEST(ForwardBackwardValid, InconsistentFlowIsInvalidBeyondTheTolerance) {
  const int h = 6, w = 6;
  OpticalFlowOptions options;  // alpha 0.01, beta 0.5 px^2
  // |f + b|^2 = 0.49 < 0.01 * (0 + 0.49) + 0.5: valid.
  cv::Mat valid =
      ForwardBackwardValid(ConstantFlow(h, w, 0, 0), ConstantFlow(h, w, 0.7f, 0), options);
  EXPECT_EQ(cv::countNonZero(valid), h * w);
  // |f + b|^2 = 1 > 0.01 + 0.5: invalid everywhere.
  valid = ForwardBackwardValid(ConstantFlow(h, w, 0, 0), ConstantFlow(h, w, 1, 0), options);
  EXPECT_EQ(cv::countNonZero(valid), 0);
  // A larger relative tolerance accepts it: 1 < 0.6 * 1 + 0.5.
  options.fb_alpha = 0.6;
  valid = ForwardBackwardValid(ConstantFlow(h, w, 0, 0), ConstantFlow(h, w, 1, 0), options);
  EXPECT_EQ(cv::countNonZero(valid), h * w);
}

TEST(OpticalFlowOptions, NegativeOrNonFiniteTolerancesAreErrors) {
  OpticalFlowOptions options;
  EXPECT_NO_THROW(options.Check());
  options.fb_alpha = -0.1;
  EXPECT_THROW(options.Check(), InputError);
  options.fb_alpha = 0.01;
  options.fb_beta = std::nan("");
  EXPECT_THROW(options.Check(), InputError);
}

TEST(ComputeDisFlow, RecoversAShiftOfATexturedImage) {
  // A smooth texture shifted by (2, 1) px between the frames.
  const int h = 64, w = 80;
  cv::Mat from(h, w, CV_8UC3), to(h, w, CV_8UC3);
  auto texture = [](double x, double y) {
    return 127.5 + 60 * std::sin(0.31 * x + 0.11 * y) + 60 * std::cos(0.23 * y - 0.07 * x);
  };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const auto a = cv::saturate_cast<uchar>(texture(x, y));
      const auto b = cv::saturate_cast<uchar>(texture(x - 2, y - 1));
      from.at<cv::Vec3b>(y, x) = cv::Vec3b(a, a, a);
      to.at<cv::Vec3b>(y, x) = cv::Vec3b(b, b, b);
    }
  }
  for (DisPreset preset : {DisPreset::kMedium, DisPreset::kFine}) {
    const cv::Mat flow = ComputeDisFlow(from, to, preset);
    ASSERT_EQ(flow.type(), CV_32FC2);
    ASSERT_EQ(flow.size(), from.size());
    // The median over the interior is the shift.
    std::vector<float> u, v;
    for (int y = 16; y < h - 16; ++y) {
      for (int x = 16; x < w - 16; ++x) {
        u.push_back(flow.at<cv::Vec2f>(y, x)[0]);
        v.push_back(flow.at<cv::Vec2f>(y, x)[1]);
      }
    }
    std::nth_element(u.begin(), u.begin() + u.size() / 2, u.end());
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    EXPECT_NEAR(u[u.size() / 2], 2.0, 0.25) << static_cast<int>(preset);
    EXPECT_NEAR(v[v.size() / 2], 1.0, 0.25) << static_cast<int>(preset);
  }
}

}  // namespace
}  // namespace banmo
