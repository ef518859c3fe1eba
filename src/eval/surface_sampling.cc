#include "banmo/eval/surface_sampling.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

// splitmix64 (Steele, Lea, Flood 2014): a tiny, well-mixed, portable stream.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1) with 53 random bits.
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

double TriangleArea(const TriangleMesh& mesh, int f) {
  const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, f));
  const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, f));
  const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, f));
  return 0.5 * (b - a).cross(c - a).norm();
}

}  // namespace

double MeshArea(const TriangleMesh& mesh) {
  double area = 0.0;
  for (int f = 0; f < mesh.NumFaces(); ++f) area += TriangleArea(mesh, f);
  return area;
}

Eigen::Matrix3Xd SampleSurface(const TriangleMesh& mesh, int num_samples, std::uint64_t seed,
                               std::vector<int>* faces) {
  CHECK_GE(num_samples, 0);
  const int num_faces = mesh.NumFaces();
  std::vector<double> cumulative(static_cast<std::size_t>(num_faces));
  double total = 0.0;
  for (int f = 0; f < num_faces; ++f) {
    total += TriangleArea(mesh, f);
    cumulative[static_cast<std::size_t>(f)] = total;
  }
  if (!(total > 0.0) || !std::isfinite(total)) {
    ThrowInputError("mesh has no triangle with positive area (", num_faces,
                    " faces); surface sampling needs a surface");
  }
  SplitMix64 rng(seed);
  Eigen::Matrix3Xd samples(3, num_samples);
  if (faces != nullptr) faces->resize(static_cast<std::size_t>(num_samples));
  for (int i = 0; i < num_samples; ++i) {
    // Pick a face by area: the first whose cumulative area exceeds u * total
    // (zero-area faces are never picked).
    const double u = rng.Uniform() * total;
    const auto it = std::upper_bound(cumulative.begin(), cumulative.end(), u);
    const int f = static_cast<int>(std::min<std::ptrdiff_t>(
        it - cumulative.begin(), static_cast<std::ptrdiff_t>(num_faces) - 1));
    if (faces != nullptr) (*faces)[static_cast<std::size_t>(i)] = f;
    const double sa = std::sqrt(rng.Uniform());
    const double b = rng.Uniform();
    samples.col(i) = (1.0 - sa) * mesh.vertices.col(mesh.faces(0, f)) +
                     sa * (1.0 - b) * mesh.vertices.col(mesh.faces(1, f)) +
                     sa * b * mesh.vertices.col(mesh.faces(2, f));
  }
  return samples;
}

Eigen::Matrix3Xd ShuffleColumns(const Eigen::Matrix3Xd& points, std::uint64_t seed) {
  Eigen::Matrix3Xd out = points;
  SplitMix64 rng(seed);
  for (Eigen::Index i = out.cols() - 1; i > 0; --i) {
    // j uniform in [0, i] (the modulo bias is below 2^-40 for any mesh size).
    const auto j = static_cast<Eigen::Index>(rng.Next() % static_cast<std::uint64_t>(i + 1));
    out.col(i).swap(out.col(j));
  }
  return out;
}

}  // namespace banmo
