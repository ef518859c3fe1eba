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

// Every triangle split into n x n smaller ones (barycentric grid, vertices
// not shared between triangles): the same surface with many more vertices.
inline TriangleMesh SplitEachTriangle(const TriangleMesh& mesh, int n) {
  TriangleMesh out;
  const int per_face_vertices = (n + 1) * (n + 2) / 2;
  out.vertices.resize(3, mesh.NumFaces() * per_face_vertices);
  out.faces.resize(3, mesh.NumFaces() * n * n);
  int v = 0;
  int f = 0;
  for (int t = 0; t < mesh.NumFaces(); ++t) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, t));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, t));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, t));
    const int base = v;
    auto index = [&](int i, int j) {  // i + j <= n, row-major over i
      return base + i * (n + 1) - i * (i - 1) / 2 + j;
    };
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        out.vertices.col(v++) =
            a + (static_cast<double>(i) / n) * (b - a) + (static_cast<double>(j) / n) * (c - a);
      }
    }
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        out.faces.col(f++) << index(i, j), index(i + 1, j), index(i, j + 1);
        if (i + j + 1 < n)
          out.faces.col(f++) << index(i + 1, j), index(i + 1, j + 1), index(i, j + 1);
      }
    }
  }
  return out;
}

inline Eigen::Matrix3d Rotation(double degrees, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(degrees * M_PI / 180.0, axis.normalized()).toRotationMatrix();
}

}  // namespace banmo::testing
