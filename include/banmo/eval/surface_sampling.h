// Area-weighted uniform sampling of points on a triangle mesh.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "banmo/geometry/mesh.h"

namespace banmo {

// Total area of the mesh's triangles.
double MeshArea(const TriangleMesh& mesh);

// `num_samples` points distributed uniformly over the surface: a triangle is
// picked with probability proportional to its area, then a uniform point in
// it (barycentric (1 - sqrt(a), sqrt(a)(1 - b), sqrt(a) b), a, b uniform).
// Deterministic for a given seed on every platform (own splitmix64 stream, no
// std:: distributions). The samples come in random order, so any prefix is a
// uniform subsample. Two meshes with the same faces and triangle areas in
// the same proportions (e.g. similar copies) get corresponding samples for the
// same seed. Throws InputError if the mesh has no triangle of positive area.
// If `faces` is given, it receives the face index of every sample.
Eigen::Matrix3Xd SampleSurface(const TriangleMesh& mesh, int num_samples, std::uint64_t seed,
                               std::vector<int>* faces = nullptr);

// The columns of `points` in a random order (Fisher-Yates with the same
// splitmix64 stream, so the same on every platform): any prefix is then a
// uniform random subset.
Eigen::Matrix3Xd ShuffleColumns(const Eigen::Matrix3Xd& points, std::uint64_t seed);

}  // namespace banmo
