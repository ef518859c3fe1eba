// Rest-bone centres from a surface (BANMo, Yang et al. CVPR 2022, Sec. 3.2:
// bones are (re-)initialised on the canonical surface), used by the solver's
// bone re-initialisation.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "banmo/geometry/mesh.h"

namespace banmo {

// B bone centres from a surface: area-weighted k-means of the vertices
// (k-means++ seeding with `seed`, then Lloyd iterations until no assignment
// changes or 50 iterations). A centre is the mean of its cluster's surface
// points, so for a cluster that is a patch of a convex-ish part it lies
// inside the shape. Requires a mesh with at least B vertices (B >= 1; an
// InputError otherwise). Deterministic in seed.
std::vector<Eigen::Vector3d> BoneCentresFromSurface(const TriangleMesh& mesh, int num_bones,
                                                    uint32_t seed);

// k weighted k-means centres of points (3 x n, n >= k >= 1; weights >= 0
// with a positive sum): k-means++ seeding with `seed`, then Lloyd
// iterations until no assignment changes or 50 iterations. Deterministic in
// seed. BoneCentresFromSurface is this on area-weighted vertices.
std::vector<Eigen::Vector3d> WeightedKMeans(const Eigen::Matrix3Xd& points,
                                            const Eigen::VectorXd& w, int k, uint32_t seed);

}  // namespace banmo
