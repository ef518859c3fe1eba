#include "banmo/deform/bone_centres.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <limits>
#include <random>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {

std::vector<Eigen::Vector3d> BoneCentresFromSurface(const TriangleMesh& mesh, int num_bones,
                                                    uint32_t seed) {
  CHECK_GE(num_bones, 1);
  const int V = mesh.NumVertices();
  if (V < num_bones) {
    ThrowInputError("bone initialisation: the surface has ", V, " vertices, fewer than the ",
                    num_bones, " bones");
  }
  // Vertex weights: a third of the area of the incident faces (uniform if
  // the mesh has no area), so the clustering does not depend on the
  // tessellation density.
  Eigen::VectorXd w = Eigen::VectorXd::Zero(V);
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, f));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, f));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, f));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) w[mesh.faces(k, f)] += area / 3.0;
  }
  if (!(w.sum() > 0)) w.setOnes();
  return WeightedKMeans(mesh.vertices, w, num_bones, seed);
}

std::vector<Eigen::Vector3d> WeightedKMeans(const Eigen::Matrix3Xd& points,
                                            const Eigen::VectorXd& w, int k, uint32_t seed) {
  const int V = static_cast<int>(points.cols());
  CHECK_GE(k, 1);
  CHECK_GE(V, k);
  CHECK_EQ(w.size(), V);
  std::mt19937 rng(seed);
  // Draws an index with probability proportional to p (own sampler: the
  // standard distributions differ between library implementations).
  auto draw = [&](const Eigen::VectorXd& p) {
    const double total = p.sum();
    const double u = (static_cast<double>(rng()) + 0.5) / 4294967296.0 * total;
    double acc = 0.0;
    for (int i = 0; i < V; ++i) {
      acc += p[i];
      if (u < acc) return i;
    }
    for (int i = V - 1; i >= 0; --i) {
      if (p[i] > 0) return i;
    }
    return V - 1;
  };

  // k-means++ seeding.
  std::vector<Eigen::Vector3d> centres;
  centres.push_back(points.col(draw(w)));
  Eigen::VectorXd d2(V);
  for (int i = 0; i < V; ++i) d2[i] = (points.col(i) - centres[0]).squaredNorm();
  while (static_cast<int>(centres.size()) < k) {
    const Eigen::VectorXd p = w.cwiseProduct(d2);
    const int pick = p.sum() > 0 ? draw(p) : draw(w);
    centres.push_back(points.col(pick));
    for (int i = 0; i < V; ++i) {
      d2[i] = std::min(d2[i], (points.col(i) - centres.back()).squaredNorm());
    }
  }

  // Lloyd iterations.
  std::vector<int> label(V, -1);
  for (int iter = 0; iter < 50; ++iter) {
    std::vector<char> changed_chunk(V, 0);
    ParallelFor(V, [&](int begin, int end) {
      for (int i = begin; i < end; ++i) {
        int best = 0;
        double best_d = std::numeric_limits<double>::infinity();
        for (int c = 0; c < k; ++c) {
          const double d = (points.col(i) - centres[c]).squaredNorm();
          if (d < best_d) {
            best_d = d;
            best = c;
          }
        }
        if (best != label[i]) changed_chunk[i] = 1;
        label[i] = best;
      }
    });
    const bool changed =
        std::any_of(changed_chunk.begin(), changed_chunk.end(), [](char c) { return c != 0; });
    if (!changed) break;
    std::vector<Eigen::Vector3d> sum(k, Eigen::Vector3d::Zero());
    std::vector<double> mass(k, 0.0);
    for (int i = 0; i < V; ++i) {
      sum[label[i]] += w[i] * points.col(i);
      mass[label[i]] += w[i];
    }
    for (int c = 0; c < k; ++c) {
      if (mass[c] > 0) centres[c] = sum[c] / mass[c];  // an empty cluster keeps its centre
    }
  }
  return centres;
}

}  // namespace banmo
