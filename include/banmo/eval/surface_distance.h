// Closest points on a triangle surface (not on its vertices): the distance
// of the dense ground truth (docs/eval.md, "Dense ground truth").
#pragma once

#include <Eigen/Core>
#include <memory>

#include "banmo/geometry/mesh.h"

namespace banmo {

// The closest point of a point on one triangle (a, b, c), exact (Ericson,
// Real-Time Collision Detection, 2005, Sec. 5.1.5: Voronoi regions of the
// vertices, edges and face). Degenerate triangles are handled (a point of the
// segment or vertex).
Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// The surface of a mesh (its triangles of positive area), for exact
// closest-point queries. Built once: seed points on every triangle (its
// centroid if its longest edge is at most `seed_spacing`, else a barycentric
// grid with steps no longer than that), each remembering its triangle, in a
// FLANN kd-tree (KdTree3). Every point of a triangle is then within
// `SeedCover()` (<= seed_spacing / sqrt(3)) of a seed on that triangle. A
// query evaluates the triangles of its 4 nearest seeds
// (ClosestPointOnTriangle); a triangle closer than the best point found so
// far has a seed within best + cover, so if the 4th seed is at least that
// far the result is exact; otherwise every seed within that radius is
// evaluated too (KdTree3::WithinRadius), which makes it exact. Queries may
// be issued from several threads.
class TriangleSurface3 {
 public:
  // Copies the triangles of `mesh` whose area is positive and finite, with every vertex
  // multiplied by `scale` (> 0), and builds the seeds (seed_spacing > 0, in
  // the scaled units) and their tree. The spacing only changes the speed,
  // never the result: 0.04 was the fastest on the Fox and a 36k-vertex mesh
  // in the normalised units of the evaluation (0.005 to 0.32 measured,
  // benchmarks/eval/README.md). Triangles too long for `max_seeds` seeds at
  // that spacing (a diverged solve's mesh, edges of 1e6) get a wider one,
  // again without changing the result. Throws InputError if no triangle has
  // a positive, finite area or a face index is out of range.
  explicit TriangleSurface3(const TriangleMesh& mesh, double scale = 1.0,
                            double seed_spacing = 0.04, double max_seeds = 4e6);
  ~TriangleSurface3();
  TriangleSurface3(TriangleSurface3&&) noexcept;
  TriangleSurface3& operator=(TriangleSurface3&&) noexcept;
  TriangleSurface3(const TriangleSurface3&) = delete;
  TriangleSurface3& operator=(const TriangleSurface3&) = delete;

  // Number of triangles kept (those with positive area), of seeds, and the
  // cover radius of the seeds.
  int NumTriangles() const;
  int NumSeeds() const;
  double SeedCover() const;

  // For every query column q: the closest point of the surface and the
  // squared Euclidean distance to it. Parallel over queries (util/parallel.h).
  // `num_radius_searches` (optional) receives how many queries needed the
  // radius search.
  void Closest(const Eigen::Matrix3Xd& queries, Eigen::Matrix3Xd* closest_points,
               Eigen::VectorXd* squared_distances, int* num_radius_searches = nullptr) const;

  // Reference: the same over every triangle, O(queries x triangles). Tests.
  void ClosestBruteForce(const Eigen::Matrix3Xd& queries, Eigen::Matrix3Xd* closest_points,
                         Eigen::VectorXd* squared_distances) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace banmo
