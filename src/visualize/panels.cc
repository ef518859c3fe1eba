#include "banmo/visualize/panels.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "banmo/synth/rasterizer.h"
#include "banmo/util/logging.h"

namespace banmo {

cv::Mat ToRgb8(const cv::Mat& rgb) {
  CHECK_EQ(rgb.type(), CV_64FC3);
  cv::Mat out;
  rgb.convertTo(out, CV_8UC3, 255.0);  // saturate_cast rounds and clamps
  return out;
}

cv::Mat MaskAgreementImage(const cv::Mat& opacity, const cv::Mat& mask, double threshold) {
  CHECK_EQ(opacity.type(), CV_64FC1);
  CHECK_EQ(mask.type(), CV_64FC1);
  CHECK(opacity.size() == mask.size());
  cv::Mat out(opacity.size(), CV_8UC3);
  for (int y = 0; y < out.rows; ++y) {
    for (int x = 0; x < out.cols; ++x) {
      const double m = mask.at<double>(y, x);
      const bool rendered = opacity.at<double>(y, x) >= threshold;
      cv::Vec3b c;
      if (m < 0.0) {
        c = kMaskUnknownColor;
      } else if (m >= 0.5) {
        c = rendered ? kMaskBothColor : kMaskInputOnlyColor;
      } else {
        c = rendered ? kMaskRenderedOnlyColor : kMaskNeitherColor;
      }
      out.at<cv::Vec3b>(y, x) = c;
    }
  }
  return out;
}

cv::Mat ColorizeError(const cv::Mat& error, double max_value) {
  CHECK_EQ(error.type(), CV_64FC1);
  CHECK_GT(max_value, 0.0);
  cv::Mat gray(error.size(), CV_8UC1);
  for (int y = 0; y < error.rows; ++y) {
    for (int x = 0; x < error.cols; ++x) {
      const double e = error.at<double>(y, x);
      const double u = std::isnan(e) ? 0.0 : std::clamp(e / max_value, 0.0, 1.0);
      gray.at<unsigned char>(y, x) = static_cast<unsigned char>(std::lround(255.0 * u));
    }
  }
  cv::Mat bgr, out;
  cv::applyColorMap(gray, bgr, cv::COLORMAP_INFERNO);
  cv::cvtColor(bgr, out, cv::COLOR_BGR2RGB);
  for (int y = 0; y < error.rows; ++y) {
    for (int x = 0; x < error.cols; ++x) {
      if (std::isnan(error.at<double>(y, x))) out.at<cv::Vec3b>(y, x) = kErrorUndefinedColor;
    }
  }
  return out;
}

cv::Mat ShadeMesh(const TriangleMesh& mesh, const PinholeCamera& camera,
                  const ShadeOptions& options) {
  CHECK(camera.IsValid());
  cv::Mat out = cv::Mat::zeros(camera.height, camera.width, CV_8UC3);
  if (mesh.NumFaces() == 0) return out;
  // Area-weighted vertex normals (the cross product's length is twice the area).
  Eigen::Matrix3Xd normals = Eigen::Matrix3Xd::Zero(3, mesh.NumVertices());
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3i v = mesh.faces.col(f);
    const Eigen::Vector3d n = (mesh.vertices.col(v[1]) - mesh.vertices.col(v[0]))
                                  .cross(mesh.vertices.col(v[2]) - mesh.vertices.col(v[0]));
    for (int k = 0; k < 3; ++k) normals.col(v[k]) += n;
  }
  const bool vertex_colors = options.use_vertex_colors && mesh.HasColors();
  const synth::RasterBuffers buffers = synth::Rasterize(camera, mesh.vertices, mesh.faces);
  const Eigen::Vector4d& k = camera.intrinsics;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const int f = buffers.face.at<int>(y, x);
      if (f < 0) continue;
      const Eigen::Vector3d b = buffers.Barycentrics(x, y);
      const Eigen::Vector3i v = mesh.faces.col(f);
      Eigen::Vector3d n = Eigen::Vector3d::Zero(), base = Eigen::Vector3d::Zero();
      for (int j = 0; j < 3; ++j) {
        n += b[j] * normals.col(v[j]);
        if (vertex_colors) base += b[j] * mesh.colors.col(v[j]).cast<double>();
      }
      if (!vertex_colors) {
        base = Eigen::Vector3d(options.base_color[0], options.base_color[1], options.base_color[2]);
      }
      // The point seen at the pixel centre, and the direction to the camera.
      const Eigen::Vector3d to_camera =
          -Eigen::Vector3d((x + 0.5 - k[2]) / k[0], (y + 0.5 - k[3]) / k[1], 1.0).normalized();
      const double norm = n.norm();
      const double lambert = norm > 0.0 ? std::abs(n.dot(to_camera)) / norm : 1.0;
      const double shade = options.ambient + (1.0 - options.ambient) * lambert;
      for (int c = 0; c < 3; ++c) {
        out.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<unsigned char>(base[c] * shade);
      }
    }
  }
  return out;
}

void DrawLabel(cv::Mat* panel, const std::string& text) {
  CHECK(panel != nullptr);
  const double scale = std::max(0.25, panel->cols / 400.0);
  const int thickness = 1;
  int baseline = 0;
  const cv::Size size =
      cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &baseline);
  const cv::Point origin(2, 2 + size.height);
  cv::putText(*panel, text, origin, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0),
              thickness + 2, cv::LINE_AA);
  cv::putText(*panel, text, origin, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255),
              thickness, cv::LINE_AA);
}

cv::Mat UpscalePanel(const cv::Mat& panel, int scale) {
  CHECK_GE(scale, 1);
  if (scale == 1) return panel.clone();
  cv::Mat out;
  cv::resize(panel, out, cv::Size(panel.cols * scale, panel.rows * scale), 0, 0, cv::INTER_NEAREST);
  return out;
}

cv::Mat ConcatPanels(const std::vector<cv::Mat>& panels) {
  CHECK(!panels.empty());
  for (const cv::Mat& p : panels) {
    CHECK_EQ(p.type(), CV_8UC3);
    CHECK(p.size() == panels[0].size());
  }
  cv::Mat out;
  cv::hconcat(panels, out);
  return out;
}

std::string EncodePng(const cv::Mat& rgb8) {
  CHECK_EQ(rgb8.type(), CV_8UC3);
  cv::Mat bgr;
  cv::cvtColor(rgb8, bgr, cv::COLOR_RGB2BGR);
  std::vector<unsigned char> bytes;
  CHECK(cv::imencode(".png", bgr, bytes)) << "PNG encoding failed";
  return std::string(bytes.begin(), bytes.end());
}

}  // namespace banmo
