// KeepLargestComponent with CGAL (kept in its own file: CGAL headers are slow
// to compile).
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <vector>

#include "banmo/extract/marching_cubes.h"

namespace banmo {

TriangleMesh KeepLargestComponent(const TriangleMesh& mesh) {
  using Kernel = CGAL::Simple_cartesian<double>;
  using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
  using FaceIndex = SurfaceMesh::Face_index;
  if (mesh.NumFaces() == 0) return RemoveUnreferencedVertices(mesh);

  // Vertex i of the Surface_mesh is vertex i of the input; faces are added in
  // order, and sm_to_input maps them back. A face the halfedge structure
  // cannot take (a non-manifold configuration; never produced by
  // MarchingCubes) is skipped here and counted as its own one-face component.
  SurfaceMesh sm;
  sm.reserve(mesh.NumVertices(), 3 * mesh.NumFaces() / 2, mesh.NumFaces());
  std::vector<SurfaceMesh::Vertex_index> vertex(mesh.NumVertices());
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    vertex[v] = sm.add_vertex(
        Kernel::Point_3(mesh.vertices(0, v), mesh.vertices(1, v), mesh.vertices(2, v)));
  }
  std::vector<int> sm_to_input;
  sm_to_input.reserve(mesh.NumFaces());
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const FaceIndex face =
        sm.add_face(vertex[mesh.faces(0, f)], vertex[mesh.faces(1, f)], vertex[mesh.faces(2, f)]);
    if (face != SurfaceMesh::null_face()) sm_to_input.push_back(f);
  }

  auto component = sm.add_property_map<FaceIndex, std::size_t>("f:component", 0).first;
  const std::size_t num_components =
      CGAL::Polygon_mesh_processing::connected_components(sm, component);
  std::vector<int> size(num_components, 0), first_face(num_components, mesh.NumFaces());
  for (FaceIndex face : sm.faces()) {
    const std::size_t c = component[face];
    ++size[c];
    first_face[c] = std::min(first_face[c], sm_to_input[static_cast<std::size_t>(face)]);
  }
  std::size_t best = 0;
  for (std::size_t c = 1; c < num_components; ++c) {
    if (size[c] > size[best] || (size[c] == size[best] && first_face[c] < first_face[best])) {
      best = c;
    }
  }

  TriangleMesh kept;
  kept.vertices = mesh.vertices;
  kept.colors = mesh.colors;
  if (num_components == 0 || size[best] < 1) {
    kept.faces.resize(3, std::min(1, mesh.NumFaces()));
    kept.faces.col(0) = mesh.faces.col(0);
    return RemoveUnreferencedVertices(kept);
  }
  kept.faces.resize(3, size[best]);
  int out = 0;
  for (FaceIndex face : sm.faces()) {
    if (component[face] == best) {
      kept.faces.col(out++) = mesh.faces.col(sm_to_input[static_cast<std::size_t>(face)]);
    }
  }
  // sm.faces() iterates in index order, i.e. input order: faces keep their
  // relative order.
  return RemoveUnreferencedVertices(kept);
}

}  // namespace banmo
