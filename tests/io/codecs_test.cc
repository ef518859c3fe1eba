// io/codecs.h: strict PNG reading, KITTI flow encoding, finiteness checks.
#include "banmo/io/codecs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "../common/input_error.h"
#include "banmo/util/error.h"

namespace banmo {
namespace {

std::string EncodePng(const cv::Mat& image) {
  std::vector<uchar> bytes;
  EXPECT_TRUE(cv::imencode(".png", image, bytes));
  return std::string(bytes.begin(), bytes.end());
}

using testing::ErrorOf;

TEST(PngInfo, ReadsTheHeaderOfEachKind) {
  const PngInfo grey8 = ParsePngInfo(EncodePng(cv::Mat(7, 5, CV_8UC1, cv::Scalar(3))), "g");
  EXPECT_EQ(grey8.width, 5);
  EXPECT_EQ(grey8.height, 7);
  EXPECT_EQ(grey8.bit_depth, 8);
  EXPECT_EQ(grey8.channels, 1);
  const PngInfo rgb16 =
      ParsePngInfo(EncodePng(cv::Mat(4, 9, CV_16UC3, cv::Scalar(1, 2, 3))), "rgb");
  EXPECT_EQ(rgb16.width, 9);
  EXPECT_EQ(rgb16.height, 4);
  EXPECT_EQ(rgb16.bit_depth, 16);
  EXPECT_EQ(rgb16.channels, 3);
  EXPECT_EQ(ParsePngInfo(EncodePng(cv::Mat(2, 2, CV_8UC4, cv::Scalar::all(9))), "a").channels, 4);
}

TEST(PngInfo, NotAPngIsAnErrorNamingTheFile) {
  EXPECT_NE(ErrorOf([] { ParsePngInfo("GIF89a not a png at all", "frame.png"); }).find("frame.png"),
            std::string::npos);
  EXPECT_THROW(ParsePngInfo("", "empty.png"), InputError);
}

TEST(CheckPngComplete, CatchesATruncatedFile) {
  const std::string png = EncodePng(cv::Mat(16, 16, CV_8UC3, cv::Scalar(10, 20, 30)));
  EXPECT_EQ(CheckPngComplete(png, "ok.png").width, 16);
  const std::string cut = png.substr(0, png.size() - 12);  // IEND gone
  EXPECT_NE(ErrorOf([&] { CheckPngComplete(cut, "cut.png"); }).find("cut.png"), std::string::npos);
  EXPECT_THROW(DecodePngStrict(cut, "cut.png", CV_8U, 3), InputError);
}

TEST(DecodePngStrict, ChecksDepthChannelsAndSize) {
  cv::Mat image(6, 8, CV_16UC1);
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) image.at<uint16_t>(y, x) = static_cast<uint16_t>(1000 * y + x);
  }
  const std::string png = EncodePng(image);
  const cv::Mat decoded = DecodePngStrict(png, "depth.png", CV_16U, 1, 8, 6);
  ASSERT_EQ(decoded.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(decoded, image, cv::NORM_INF), 0.0);
  EXPECT_THROW(DecodePngStrict(png, "depth.png", CV_8U, 1), InputError);
  EXPECT_THROW(DecodePngStrict(png, "depth.png", CV_16U, 3), InputError);
  const std::string size_error =
      ErrorOf([&] { DecodePngStrict(png, "depth.png", CV_16U, 1, 9, 6); });
  EXPECT_NE(size_error.find("depth.png"), std::string::npos);
}

TEST(KittiFlow, RoundTripsToASixtyFourthOfAPixel) {
  cv::Mat flow(3, 4, CV_32FC2), valid(3, 4, CV_8UC1, cv::Scalar(255));
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) flow.at<cv::Vec2f>(y, x) = cv::Vec2f(-100.3f + 37 * x, 2.2f * y);
  }
  valid.at<uchar>(1, 2) = 0;
  int clamped = -1;
  const cv::Mat encoded = EncodeFlowKitti(flow, valid, &clamped);
  EXPECT_EQ(clamped, 0);
  ASSERT_EQ(encoded.type(), CV_16UC3);
  // BGR order: B holds the valid bit, R = u * 64 + 2^15.
  EXPECT_EQ(encoded.at<cv::Vec3w>(0, 0)[0], 1);
  EXPECT_EQ(encoded.at<cv::Vec3w>(1, 2)[0], 0);
  EXPECT_EQ(encoded.at<cv::Vec3w>(0, 0)[2], static_cast<int>(std::lround(-100.3 * 64 + 32768)));
  cv::Mat flow2, valid2;
  DecodeFlowKitti(encoded, "flow.png", &flow2, &valid2);
  ASSERT_EQ(flow2.type(), CV_32FC2);
  ASSERT_EQ(valid2.type(), CV_8UC1);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) {
      EXPECT_EQ(valid2.at<uchar>(y, x), valid.at<uchar>(y, x));
      if (valid.at<uchar>(y, x) == 0) continue;
      for (int c = 0; c < 2; ++c) {
        EXPECT_NEAR(flow2.at<cv::Vec2f>(y, x)[c], flow.at<cv::Vec2f>(y, x)[c], 0.5 / 64 + 1e-6);
      }
    }
  }
}

TEST(KittiFlow, OutOfRangeFlowIsClampedAndInvalid) {
  cv::Mat flow(1, 2, CV_32FC2), valid(1, 2, CV_8UC1, cv::Scalar(255));
  flow.at<cv::Vec2f>(0, 0) = cv::Vec2f(600.0f, 0.0f);
  flow.at<cv::Vec2f>(0, 1) = cv::Vec2f(1.0f, -1.0f);
  int clamped = 0;
  const cv::Mat encoded = EncodeFlowKitti(flow, valid, &clamped);
  EXPECT_EQ(clamped, 1);
  cv::Mat flow2, valid2;
  DecodeFlowKitti(encoded, "flow.png", &flow2, &valid2);
  EXPECT_EQ(valid2.at<uchar>(0, 0), 0);
  EXPECT_EQ(valid2.at<uchar>(0, 1), 255);
  EXPECT_LT(flow2.at<cv::Vec2f>(0, 0)[0], 512.0f);
}

TEST(KittiFlow, AValidChannelOtherThanZeroOrOneIsAnError) {
  cv::Mat bad(2, 2, CV_16UC3, cv::Scalar(1, 32768, 32768));
  bad.at<cv::Vec3w>(1, 1)[0] = 7;
  cv::Mat flow, valid;
  EXPECT_NE(ErrorOf([&] { DecodeFlowKitti(bad, "flow_07.png", &flow, &valid); }).find("flow_07"),
            std::string::npos);
}

TEST(AllFinite, FindsTheFirstBadElementInRowMajorOrder) {
  cv::Mat m(3, 4, CV_32FC2, cv::Scalar(1, 2));
  cv::Vec3i bad(-1, -1, -1);
  EXPECT_TRUE(AllFinite(m, &bad));
  m.at<cv::Vec2f>(2, 0)[0] = std::numeric_limits<float>::infinity();
  m.at<cv::Vec2f>(1, 3)[1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(AllFinite(m, &bad));
  EXPECT_EQ(bad, cv::Vec3i(1, 3, 1));
  cv::Mat d(2, 2, CV_64FC1, cv::Scalar(0));
  EXPECT_TRUE(AllFinite(d));
  d.at<double>(0, 1) = -std::numeric_limits<double>::infinity();
  EXPECT_FALSE(AllFinite(d));
  cv::Mat h;
  cv::Mat(2, 2, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN())).convertTo(h, CV_16F);
  EXPECT_FALSE(AllFinite(h));
}

}  // namespace
}  // namespace banmo
