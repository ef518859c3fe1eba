// Triangle mesh container shared by synth, extraction and evaluation.
#pragma once

#include <Eigen/Core>
#include <cstdint>

namespace banmo {

struct TriangleMesh {
  // One column per vertex (3 x V, column-major, i.e. contiguous xyz triples,
  // which is also the row-major V x 3 layout FLANN expects).
  Eigen::Matrix3Xd vertices;
  // One column per triangle: vertex indices, counter-clockwise seen from
  // outside.
  Eigen::Matrix3Xi faces;
  // Optional per-vertex colours (3 x V, RGB in [0, 255]); empty if absent.
  Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic> colors;

  int NumVertices() const { return static_cast<int>(vertices.cols()); }
  int NumFaces() const { return static_cast<int>(faces.cols()); }
  bool HasColors() const { return colors.cols() == vertices.cols() && colors.cols() > 0; }
};

}  // namespace banmo
