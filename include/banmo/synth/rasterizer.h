// Z-buffered triangle rasteriser with perspective-correct barycentrics.
//
// Sampling rule: a pixel (column i, row j) is covered by a triangle when its
// centre (i + 0.5, j + 0.5) lies inside or on the edge of the projected
// triangle (inclusive edges, both windings: no back-face culling). Of the
// triangles covering a pixel, the one with the smallest camera z at the
// pixel centre wins (ties: the lower face index). Barycentrics are
// perspective-correct: with screen-space barycentrics l_k and vertex depths
// z_k, b_k = (l_k / z_k) / sum_m (l_m / z_m), and the depth is
// z = 1 / sum_m (l_m / z_m) (exact for a planar triangle).
// Triangles with a vertex closer than `near` are skipped (not clipped):
// synthetic scenes keep the object ~3 units away.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "banmo/geometry/camera.h"

namespace banmo::synth {

struct RasterBuffers {
  cv::Mat face;   // CV_32SC1: index of the visible triangle, -1 for background
  cv::Mat bary;   // CV_32FC2: perspective-correct barycentrics (b1, b2); b0 = 1 - b1 - b2
  cv::Mat depth;  // CV_32FC1: camera z of the visible surface, 0 for background

  // Barycentrics of pixel (x, y) as (b0, b1, b2).
  Eigen::Vector3d Barycentrics(int x, int y) const {
    const cv::Vec2f b = bary.at<cv::Vec2f>(y, x);
    return Eigen::Vector3d(1.0 - b[0] - b[1], b[0], b[1]);
  }
};

// Rasterises `faces` of a mesh whose vertices are given in camera coordinates.
RasterBuffers Rasterize(const PinholeCamera& camera, const Eigen::Matrix3Xd& vertices_in_camera,
                        const Eigen::Matrix3Xi& faces, double near = 0.01);

}  // namespace banmo::synth
