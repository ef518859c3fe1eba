// Helpers shared by the extraction tests: vertex-manifold check and a
// point-in-mesh test by generalised winding number.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "banmo/geometry/mesh.h"

namespace banmo {
namespace testing_util {

// Number of vertices whose incident faces do not form one disk (or one fan
// for a boundary vertex): the link of each vertex (the opposite edges of its
// faces) must be a single path or cycle.
inline int CountNonManifoldVertices(const TriangleMesh& mesh) {
  std::vector<std::vector<std::pair<int, int>>> link(mesh.NumVertices());
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      link[mesh.faces(k, f)].emplace_back(mesh.faces((k + 1) % 3, f), mesh.faces((k + 2) % 3, f));
    }
  }
  int bad = 0;
  for (const auto& edges : link) {
    if (edges.empty()) continue;
    // Walk the link from the first edge; in a disk the walk visits every
    // edge exactly once.
    std::map<int, int> next;
    bool duplicate = false;
    for (const auto& [a, b] : edges) duplicate |= !next.emplace(a, b).second;
    if (duplicate) {
      ++bad;
      continue;
    }
    // Start at a link vertex with no predecessor (boundary) if any.
    std::map<int, int> has_prev;
    for (const auto& [a, b] : edges) has_prev[b] = 1;
    int start = edges[0].first;
    for (const auto& [a, b] : edges) {
      if (!has_prev.count(a)) start = a;
    }
    int visited = 0;
    int x = start;
    while (next.count(x) && visited <= static_cast<int>(edges.size())) {
      x = next[x];
      ++visited;
      if (x == start) break;
    }
    if (visited != static_cast<int>(edges.size())) ++bad;
  }
  return bad;
}

// Generalised winding number of a closed oriented mesh at p (1 inside, 0
// outside), from the solid angles of the triangles (Van Oosterom & Strackee).
inline double WindingNumber(const TriangleMesh& mesh, const Eigen::Vector3d& p) {
  double total = 0.0;
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, f)) - p;
    const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, f)) - p;
    const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, f)) - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    total += 2.0 * std::atan2(num, den);
  }
  return total / (4.0 * M_PI);
}

}  // namespace testing_util
}  // namespace banmo
