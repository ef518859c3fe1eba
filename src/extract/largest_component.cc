// KeepLargestComponent and KeepLargeComponents with CGAL (kept in its own file: CGAL headers are
// slow to compile).
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "banmo/extract/marching_cubes.h"

namespace banmo {

namespace {

// Labels the faces of `mesh` by connected component (faces connected through
// shared edges). A face the halfedge structure cannot take (a non-manifold
// configuration; never produced by MarchingCubes) is its own component.
// Returns the number of components; label[f] is face f's component and
// size[c], first_face[c] each component's face count and lowest face index.
int LabelComponents(const TriangleMesh& mesh, std::vector<int>* label, std::vector<int>* size,
                    std::vector<int>* first_face) {
  using Kernel = CGAL::Simple_cartesian<double>;
  using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
  using FaceIndex = SurfaceMesh::Face_index;
  // Vertex i of the Surface_mesh is vertex i of the input; faces are added in
  // order, and sm_to_input maps them back.
  SurfaceMesh sm;
  sm.reserve(mesh.NumVertices(), 3 * mesh.NumFaces() / 2, mesh.NumFaces());
  std::vector<SurfaceMesh::Vertex_index> vertex(mesh.NumVertices());
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    vertex[v] = sm.add_vertex(
        Kernel::Point_3(mesh.vertices(0, v), mesh.vertices(1, v), mesh.vertices(2, v)));
  }
  std::vector<int> sm_to_input;
  sm_to_input.reserve(mesh.NumFaces());
  label->assign(mesh.NumFaces(), -1);
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const FaceIndex face =
        sm.add_face(vertex[mesh.faces(0, f)], vertex[mesh.faces(1, f)], vertex[mesh.faces(2, f)]);
    if (face != SurfaceMesh::null_face()) sm_to_input.push_back(f);
  }
  auto component = sm.add_property_map<FaceIndex, std::size_t>("f:component", 0).first;
  int num_components =
      static_cast<int>(CGAL::Polygon_mesh_processing::connected_components(sm, component));
  for (FaceIndex face : sm.faces()) {
    (*label)[sm_to_input[static_cast<std::size_t>(face)]] = static_cast<int>(component[face]);
  }
  for (int& l : *label) {
    if (l < 0) l = num_components++;  // a face the Surface_mesh refused
  }
  size->assign(num_components, 0);
  first_face->assign(num_components, mesh.NumFaces());
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const int c = (*label)[f];
    ++(*size)[c];
    (*first_face)[c] = std::min((*first_face)[c], f);
  }
  return num_components;
}

// The faces whose component keep[c] is true, in input order; unreferenced
// vertices dropped (colours follow their vertices).
TriangleMesh KeepFaces(const TriangleMesh& mesh, const std::vector<int>& label,
                       const std::vector<bool>& keep) {
  TriangleMesh kept;
  kept.vertices = mesh.vertices;
  kept.colors = mesh.colors;
  int count = 0;
  for (int f = 0; f < mesh.NumFaces(); ++f) count += keep[label[f]] ? 1 : 0;
  kept.faces.resize(3, count);
  int out = 0;
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    if (keep[label[f]]) kept.faces.col(out++) = mesh.faces.col(f);
  }
  return RemoveUnreferencedVertices(kept);
}

}  // namespace

TriangleMesh KeepLargestComponent(const TriangleMesh& mesh) {
  if (mesh.NumFaces() == 0) return RemoveUnreferencedVertices(mesh);
  std::vector<int> label, size, first_face;
  const int n = LabelComponents(mesh, &label, &size, &first_face);
  int best = 0;
  for (int c = 1; c < n; ++c) {
    if (size[c] > size[best] || (size[c] == size[best] && first_face[c] < first_face[best])) {
      best = c;
    }
  }
  std::vector<bool> keep(n, false);
  keep[best] = true;
  return KeepFaces(mesh, label, keep);
}

TriangleMesh KeepLargeComponents(const TriangleMesh& mesh, double min_fraction) {
  CHECK(std::isfinite(min_fraction) && min_fraction >= 0.0 && min_fraction <= 1.0)
      << "min_fraction must be in [0, 1], got " << min_fraction;
  if (min_fraction >= 1.0) return KeepLargestComponent(mesh);
  if (mesh.NumFaces() == 0) return RemoveUnreferencedVertices(mesh);
  std::vector<int> label, size, first_face;
  const int n = LabelComponents(mesh, &label, &size, &first_face);
  const int largest = *std::max_element(size.begin(), size.end());
  std::vector<bool> keep(n, false);
  for (int c = 0; c < n; ++c) keep[c] = size[c] >= min_fraction * largest;
  return KeepFaces(mesh, label, keep);
}

}  // namespace banmo
