// Procedural meshes with known geometry for the eval tests and benchmarks.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "banmo/geometry/mesh.h"

namespace banmo::testing {

// UV sphere of `radius` about `center` with its poles on the y axis:
// (rings - 1) latitude rings of `segments` vertices plus two poles. With
// segments divisible by 4, vertices at z = center.z exist on every ring.
inline TriangleMesh UvSphere(double radius, const Eigen::Vector3d& center, int rings = 32,
                             int segments = 64) {
  TriangleMesh mesh;
  const int num_vertices = 2 + (rings - 1) * segments;
  mesh.vertices.resize(3, num_vertices);
  mesh.vertices.col(0) = center + Eigen::Vector3d(0, radius, 0);
  mesh.vertices.col(num_vertices - 1) = center - Eigen::Vector3d(0, radius, 0);
  for (int i = 1; i < rings; ++i) {
    const double theta = M_PI * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * M_PI * j / segments;
      mesh.vertices.col(1 + (i - 1) * segments + j) =
          center + radius * Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::cos(theta),
                                            std::sin(theta) * std::sin(phi));
    }
  }
  const int num_faces = 2 * segments + 2 * (rings - 2) * segments;
  mesh.faces.resize(3, num_faces);
  int f = 0;
  auto ring = [&](int i, int j) {
    return 1 + (i - 1) * segments + ((j % segments) + segments) % segments;
  };
  for (int j = 0; j < segments; ++j) {
    mesh.faces.col(f++) << 0, ring(1, j + 1), ring(1, j);
    mesh.faces.col(f++) << num_vertices - 1, ring(rings - 1, j), ring(rings - 1, j + 1);
  }
  for (int i = 1; i < rings - 1; ++i) {
    for (int j = 0; j < segments; ++j) {
      mesh.faces.col(f++) << ring(i, j), ring(i, j + 1), ring(i + 1, j + 1);
      mesh.faces.col(f++) << ring(i, j), ring(i + 1, j + 1), ring(i + 1, j);
    }
  }
  return mesh;
}

// An asymmetric blob (no rotational symmetry, so ICP has one answer): a unit
// sphere about the origin with radius 1 + 0.25 sin(2 theta) cos(3 phi) + 0.15 y
// and stretched along x, then moved to `center`.
inline TriangleMesh Blob(const Eigen::Vector3d& center, int rings = 32, int segments = 64) {
  TriangleMesh mesh = UvSphere(1.0, Eigen::Vector3d::Zero(), rings, segments);
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    const Eigen::Vector3d u = mesh.vertices.col(i);
    const double theta = std::acos(std::clamp(u.y(), -1.0, 1.0));
    const double phi = std::atan2(u.z(), u.x());
    const double r = 1.0 + 0.25 * std::sin(2 * theta) * std::cos(3 * phi) + 0.15 * u.y();
    mesh.vertices.col(i) = center + Eigen::Vector3d(1.4 * r * u.x(), r * u.y(), 0.8 * r * u.z());
  }
  return mesh;
}

// Applies y = s R x + t to the vertices.
inline TriangleMesh Transformed(const TriangleMesh& mesh, double s, const Eigen::Matrix3d& r,
                                const Eigen::Vector3d& t) {
  TriangleMesh out = mesh;
  out.vertices = ((s * r) * mesh.vertices).colwise() + t;
  return out;
}

inline Eigen::Matrix3d Rotation(double degrees, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(degrees * M_PI / 180.0, axis.normalized()).toRotationMatrix();
}

}  // namespace banmo::testing
