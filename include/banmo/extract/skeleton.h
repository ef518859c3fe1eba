// Curve skeletons of closed surfaces and bone sites along them.
//
// A surface's mean-curvature-flow skeleton (Tagliasacchi et al. 2012, CGAL's
// Mean_curvature_flow_skeletonization) is a graph of curves along the middle
// of its parts: a spine, one curve per leg, tail, neck. Bone centres from
// k-means of points spread uniformly along it give each part bones in
// proportion to its length, where k-means of the surface (deform/bone_centres.h)
// gives them in proportion to its area, so thin limbs get few or none.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "banmo/geometry/mesh.h"

namespace banmo {

// The skeleton's edges as segments: column j of *from / *to are the ends of
// edge j. The mesh must be a closed, manifold triangle mesh (an InputError
// otherwise, naming what is wrong).
void CurveSkeleton(const TriangleMesh& mesh, Eigen::Matrix3Xd* from, Eigen::Matrix3Xd* to);

// num_bones centres: weighted k-means (WeightedKMeans, deform/bone_centres.h;
// seed) of points every L / (32 num_bones) along the skeleton of total
// length L, each weighted by the length it stands for. An InputError when
// the mesh is not closed and manifold or its skeleton is degenerate (no
// length); the caller may fall back to BoneCentresFromSurface. Not
// bit-reproducible: CGAL orders the flow's edge collapses by address, so
// two calls on one mesh can give skeletons a fraction of a grid cell apart
// and k-means centres a little apart (tests/extract/skeleton_test.cc).
std::vector<Eigen::Vector3d> BoneCentresFromSkeleton(const TriangleMesh& mesh, int num_bones,
                                                     uint32_t seed);

}  // namespace banmo
