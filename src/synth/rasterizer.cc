#include "banmo/synth/rasterizer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace banmo::synth {

RasterBuffers Rasterize(const PinholeCamera& camera, const Eigen::Matrix3Xd& vertices_in_camera,
                        const Eigen::Matrix3Xi& faces, double near) {
  const int w = camera.width, h = camera.height;
  RasterBuffers out;
  out.face.create(h, w, CV_32SC1);
  out.face.setTo(-1);
  out.bary.create(h, w, CV_32FC2);
  out.bary.setTo(cv::Scalar(0, 0));
  out.depth.create(h, w, CV_32FC1);
  out.depth.setTo(0);
  std::vector<double> zbuf(static_cast<size_t>(w) * h, std::numeric_limits<double>::infinity());

  const double fx = camera.intrinsics[0], fy = camera.intrinsics[1];
  const double cx = camera.intrinsics[2], cy = camera.intrinsics[3];
  const int nv = static_cast<int>(vertices_in_camera.cols());
  std::vector<Eigen::Vector2d> uv(nv);
  for (int i = 0; i < nv; ++i) {
    const Eigen::Vector3d& p = vertices_in_camera.col(i);
    const double z = std::max(p.z(), kMinProjectionDepth);
    uv[i] = Eigen::Vector2d(fx * p.x() / z + cx, fy * p.y() / z + cy);
  }
  for (int f = 0; f < faces.cols(); ++f) {
    const int ia = faces(0, f), ib = faces(1, f), ic = faces(2, f);
    const double za = vertices_in_camera(2, ia), zb = vertices_in_camera(2, ib),
                 zc = vertices_in_camera(2, ic);
    if (za < near || zb < near || zc < near) continue;
    const Eigen::Vector2d a = uv[ia], b = uv[ib], c = uv[ic];
    // Twice the signed screen area.
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (!(std::abs(area) > 1e-12)) continue;
    const double umin = std::min({a.x(), b.x(), c.x()}), umax = std::max({a.x(), b.x(), c.x()});
    const double vmin = std::min({a.y(), b.y(), c.y()}), vmax = std::max({a.y(), b.y(), c.y()});
    // Pixel centres i + 0.5 within [umin, umax].
    const int i0 = std::max(0, static_cast<int>(std::ceil(umin - 0.5)));
    const int i1 = std::min(w - 1, static_cast<int>(std::floor(umax - 0.5)));
    const int j0 = std::max(0, static_cast<int>(std::ceil(vmin - 0.5)));
    const int j1 = std::min(h - 1, static_cast<int>(std::floor(vmax - 0.5)));
    if (i0 > i1 || j0 > j1) continue;
    const double inv_area = 1.0 / area;
    for (int j = j0; j <= j1; ++j) {
      const double py = j + 0.5;
      for (int i = i0; i <= i1; ++i) {
        const double px = i + 0.5;
        // Screen-space barycentrics (edge functions over the signed area).
        const double la = ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px)) * inv_area;
        const double lb = ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px)) * inv_area;
        const double lc = 1.0 - la - lb;
        if (la < 0 || lb < 0 || lc < 0) continue;
        const double qa = la / za, qb = lb / zb, qc = lc / zc;
        const double sum = qa + qb + qc;
        const double z = 1.0 / sum;
        const size_t idx = static_cast<size_t>(j) * w + i;
        if (!(z < zbuf[idx])) continue;
        zbuf[idx] = z;
        out.face.at<int>(j, i) = f;
        out.bary.at<cv::Vec2f>(j, i) =
            cv::Vec2f(static_cast<float>(qb * z), static_cast<float>(qc * z));
        out.depth.at<float>(j, i) = static_cast<float>(z);
      }
    }
  }
  return out;
}

}  // namespace banmo::synth
