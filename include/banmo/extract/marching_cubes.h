// Marching cubes (Lorensen & Cline 1987) of the level set {X : f(X) = iso} of
// a scalar field sampled on a regular grid, plus the mesh utilities the
// extraction needs (largest connected component, topology and volume).
//
// Conventions:
//   - f < iso is inside (an SDF is negative inside); a grid node with
//     f >= iso is outside.
//   - Triangles are counter-clockwise seen from outside: their normals point
//     toward increasing f (outward for an SDF).
//   - One vertex per cut grid edge (shared by the up to 4 cells around that
//     edge), placed by linear interpolation of f along the edge.
//
// The case table is generated at start-up from the rule below instead of
// being typed in (256 cases, no transcription errors):
//   on each face of a cell, the cut edges are joined by segments that separate
//   the inside corners from the outside ones; on an ambiguous face (inside
//   corners diagonal) each inside corner is cut off on its own (the inside
//   corners are never joined across a face). The segments of the six faces
//   form closed loops on the cell boundary; each loop is triangulated as a
//   fan. Because a face's segments depend only on that face's four signs, two
//   cells sharing a face produce the same segments there, so the surface is
//   watertight (crack-free) and every vertex has a single disk of triangles
//   around it: away from the grid boundary the output is a closed, oriented
//   2-manifold. Resolving ambiguous faces by a fixed rule instead of the
//   asymptotic decider may join or split thin features differently from the
//   trilinear interpolant at the grid scale; it never creates holes.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <vector>

#include "banmo/geometry/mesh.h"

namespace banmo {

// Evaluates the field at the columns of `points` (3 x n) into values (n).
// Called with at most GridOptions::max_batch_points points at a time, from
// one thread at a time (the callback may parallelise internally).
using FieldBatchFunction =
    std::function<void(const Eigen::Matrix3Xd& points, Eigen::VectorXd* values)>;

struct GridOptions {
  // Cells along the longest edge of the box (>= 2); the other axes get the
  // number of cells that keeps cells as close to cubes as possible (spacing
  // exactly extent / cells on each axis).
  int resolution = 128;
  // Axis-aligned box sampled by the grid (max > min on every axis).
  Eigen::Vector3d bounds_min = Eigen::Vector3d::Constant(-1.0);
  Eigen::Vector3d bounds_max = Eigen::Vector3d::Constant(1.0);
  // Level extracted (0 for the SDF's zero level set).
  double iso_level = 0.0;
  // If true, the outermost layer of grid nodes is not evaluated and counts
  // as outside (value iso_level + cell spacing), so the surface is always
  // closed: a shape leaving the box is capped within one cell of the box.
  // If false, such a surface has an open boundary at the box.
  bool close_at_bounds = true;
  // Coarse-to-fine sampling: the field is first sampled at every
  // coarse_stride-th node per axis; a block of coarse_stride^3 cells is
  // sampled at full resolution only if its corners differ in sign or one of
  // them is within band * (block diagonal) of iso_level; elsewhere the fine
  // nodes take the coarse (trilinear) values, which have the corners' sign.
  // The mesh is the same as with dense sampling for any field that is
  // L-Lipschitz with L < 2 * band (every point of a block is within half a
  // diagonal of a corner, so a block holding a level-set point has a corner
  // closer than band * diagonal); an SDF has L = 1, a trained SDF MLP about 1
  // (eikonal term). 1 = dense sampling, for any field.
  int coarse_stride = 4;
  // Band half-width in block diagonals (>= 0), see coarse_stride.
  double band = 1.0;
  // Upper bound on the points per field call (>= 1): bounds the memory of
  // the MLP caches (about 5 KB per point for a width-64, 3-layer SDF MLP).
  int max_batch_points = 16384;

  // Throws InputError naming the field (prefixed by `prefix`) on a violated
  // constraint.
  void Check(const char* prefix = "grid") const;
};

// Cells per axis and spacing per axis of the grid described by options.
struct GridShape {
  Eigen::Vector3i cells;    // cells per axis (nodes = cells + 1)
  Eigen::Vector3d spacing;  // cell size per axis
};
GridShape ComputeGridShape(const GridOptions& options);

// Counts of one MarchingCubes call.
struct MarchingCubesStats {
  int64_t num_nodes = 0;      // fine grid nodes
  int64_t num_evaluated = 0;  // field evaluations (coarse and fine)
};

// Marching cubes of `field` on the grid. The field is sampled one z-slice of
// nodes at a time (two slices are kept in memory, plus the coarse grid), so
// memory is O(cells_x * cells_y + cells^3 / coarse_stride^3) besides the
// output. Throws InputError if the field returns a non-finite value (names
// the point). Returns an empty mesh when the level set does not cross the
// grid. stats (optional) receives the evaluation counts.
TriangleMesh MarchingCubes(const FieldBatchFunction& field, const GridOptions& options,
                           MarchingCubesStats* stats = nullptr);

// Keeps the connected component (faces connected through shared edges) with
// the most faces, and drops unreferenced vertices (colours follow their
// vertices). Uses CGAL's Surface_mesh / Polygon_mesh_processing. Ties go to
// the component containing the lowest face index.
TriangleMesh KeepLargestComponent(const TriangleMesh& mesh);

// Keeps every connected component with at least min_fraction times the faces
// of the largest one (min_fraction in [0, 1]; 0 keeps all, 1 is
// KeepLargestComponent), and drops unreferenced vertices. Faces keep their
// order, colours follow their vertices.
TriangleMesh KeepLargeComponents(const TriangleMesh& mesh, double min_fraction);

// Drops vertices no face references (colours follow), keeping the order.
TriangleMesh RemoveUnreferencedVertices(const TriangleMesh& mesh);

// Combinatorial and metric summary of a triangle mesh.
struct MeshStats {
  int num_vertices = 0;
  int num_faces = 0;
  int num_edges = 0;               // undirected edges
  int num_boundary_edges = 0;      // edges used by one face
  int num_nonmanifold_edges = 0;   // edges used by more than two faces
  int num_inconsistent_edges = 0;  // edges used twice in the same direction
  int num_components = 0;          // face components (through shared edges)
  int euler_characteristic = 0;    // V - E + F (over referenced vertices)
  double signed_volume = 0.0;      // (1/6) sum det(v0, v1, v2): > 0 if outward
  double area = 0.0;               // total triangle area

  // True when every edge is shared by exactly two faces with opposite
  // directions (a closed, consistently oriented surface).
  bool IsClosedOriented() const {
    return num_boundary_edges == 0 && num_nonmanifold_edges == 0 && num_inconsistent_edges == 0;
  }
};
MeshStats ComputeMeshStats(const TriangleMesh& mesh);

}  // namespace banmo
