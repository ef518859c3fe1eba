#include "banmo/eval/surface_distance.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "banmo/geometry/nearest_neighbors.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {

Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;  // vertex region a
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;  // vertex region b
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 && d1 - d3 > 0.0) {
    return a + (d1 / (d1 - d3)) * ab;  // edge ab
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;  // vertex region c
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 && d2 - d6 > 0.0) {
    return a + (d2 / (d2 - d6)) * ac;  // edge ac
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 && (d4 - d3) + (d5 - d6) > 0.0) {
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);  // edge bc
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) {
    // Degenerate (collinear) triangle: the best of its three edges.
    Eigen::Vector3d best = a;
    double best_sq = (p - a).squaredNorm();
    const Eigen::Vector3d ends[3][2] = {{a, b}, {b, c}, {c, a}};
    for (const auto& e : ends) {
      const Eigen::Vector3d d = e[1] - e[0];
      const double len_sq = d.squaredNorm();
      const double u = len_sq > 0.0 ? std::clamp((p - e[0]).dot(d) / len_sq, 0.0, 1.0) : 0.0;
      const Eigen::Vector3d x = e[0] + u * d;
      if ((p - x).squaredNorm() < best_sq) {
        best_sq = (p - x).squaredNorm();
        best = x;
      }
    }
    return best;
  }
  return a + (vb / sum) * ab + (vc / sum) * ac;  // face interior
}

struct TriangleSurface3::Impl {
  Eigen::Matrix3Xd a, b, c;        // corners of the kept triangles
  std::vector<int> seed_triangle;  // triangle of every seed
  std::unique_ptr<KdTree3> seeds;
  std::vector<double> triangle_cover;  // every point of triangle t is within this of its seeds
  double cover = 0.0;                  // the largest of them
};

namespace {
// Nearest seeds looked at first (measured 2, 4, 8, 16, 32 on the Fox and a
// 36k-vertex mesh: 2 and 4 the fastest, 8 and more slower); the radius
// search does the rest.
constexpr int kFirstSeeds = 4;
}  // namespace

TriangleSurface3::TriangleSurface3(const TriangleMesh& mesh, double scale, double seed_spacing,
                                   double max_seeds) {
  CHECK_GT(scale, 0.0);
  CHECK_GT(seed_spacing, 0.0);
  CHECK_GE(max_seeds, 1.0);
  impl_ = std::make_unique<Impl>();
  const int num_vertices = mesh.NumVertices();
  impl_->a.resize(3, mesh.NumFaces());
  impl_->b.resize(3, mesh.NumFaces());
  impl_->c.resize(3, mesh.NumFaces());
  Eigen::Index n = 0;  // triangles kept so far, in columns [0, n)
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.faces(k, f);
      if (v < 0 || v >= num_vertices) {
        ThrowInputError("face ", f, " refers to vertex ", v, " outside [0, ", num_vertices, ")");
      }
    }
    const Eigen::Vector3d a = scale * mesh.vertices.col(mesh.faces(0, f));
    const Eigen::Vector3d b = scale * mesh.vertices.col(mesh.faces(1, f));
    const Eigen::Vector3d c = scale * mesh.vertices.col(mesh.faces(2, f));
    // A positive, finite area: false for NaN, for infinite corners and for
    // edges whose squares overflow (no distance to speak of).
    const double area2 = (b - a).cross(c - a).norm();
    if (!(area2 > 0.0 && std::isfinite(area2))) continue;
    impl_->a.col(n) = a;
    impl_->b.col(n) = b;
    impl_->c.col(n) = c;
    ++n;
  }
  if (n == 0) {
    ThrowInputError("mesh has no finite triangle with positive area (", mesh.NumFaces(),
                    " faces); a surface is needed");
  }
  impl_->a.conservativeResize(3, n);
  impl_->b.conservativeResize(3, n);
  impl_->c.conservativeResize(3, n);
  // Seeds: a triangle whose longest edge e is at most seed_spacing gets its
  // centroid (every point of it is within max |corner - centroid| <= e / sqrt(3)
  // of it); a longer one the barycentric grid of step 1/m, m = ceil(e /
  // seed_spacing), whose sub-triangles are similar to it with longest edge
  // e / m: every point is within e / (m sqrt(3)) of a grid point (the largest
  // distance of a point of a triangle to its nearest corner is at most the
  // circumradius of an acute or half the longest edge of an obtuse triangle,
  // both <= longest edge / sqrt(3)).
  //
  // A surface with very long edges (a diverged solve's mesh: edges of 1e6
  // against a spacing of 0.04) would need about (e / spacing)^2 / 2 seeds a
  // triangle, more than memory holds: the spacing grows until the seeds
  // number at most max_seeds (default 4e6, 96 MB of points, far above any
  // mesh at the evaluation's spacing: the dense Fox has one a triangle) or
  // one a triangle. The result stays exact; only the searches' radius grows
  // with the cover.
  std::vector<double> longest(static_cast<std::size_t>(n));
  for (Eigen::Index t = 0; t < n; ++t) {
    const Eigen::Vector3d a = impl_->a.col(t), b = impl_->b.col(t), c = impl_->c.col(t);
    longest[static_cast<std::size_t>(t)] =
        std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  }
  // Grid steps m of a triangle with longest edge e (0: its centroid alone);
  // a double, since before the spacing widens it can pass any int.
  auto grid_steps = [&](double e) { return e <= seed_spacing ? 0.0 : std::ceil(e / seed_spacing); };
  for (;;) {
    double total = 0.0;
    for (const double e : longest) {
      const double m = grid_steps(e);
      total += m == 0.0 ? 1.0 : 0.5 * (m + 1.0) * (m + 2.0);
    }
    if (total <= std::max(max_seeds, static_cast<double>(n))) break;
    seed_spacing *= std::max(1.1, std::sqrt(total / max_seeds));
  }
  std::vector<Eigen::Vector3d> points;
  double cover = 0.0;
  for (Eigen::Index t = 0; t < n; ++t) {
    const Eigen::Vector3d a = impl_->a.col(t), b = impl_->b.col(t), c = impl_->c.col(t);
    const double e = longest[static_cast<std::size_t>(t)];
    const int m = static_cast<int>(grid_steps(e));  // at most max_seeds now
    if (m == 0) {
      const Eigen::Vector3d g = (a + b + c) / 3.0;
      points.push_back(g);
      impl_->seed_triangle.push_back(static_cast<int>(t));
      impl_->triangle_cover.push_back(std::max({(a - g).norm(), (b - g).norm(), (c - g).norm()}));
      cover = std::max(cover, impl_->triangle_cover.back());
      continue;
    }
    for (int i = 0; i <= m; ++i) {
      for (int j = 0; i + j <= m; ++j) {
        points.push_back(a + (static_cast<double>(i) / m) * (b - a) +
                         (static_cast<double>(j) / m) * (c - a));
        impl_->seed_triangle.push_back(static_cast<int>(t));
      }
    }
    impl_->triangle_cover.push_back(e / (m * std::sqrt(3.0)));
    cover = std::max(cover, impl_->triangle_cover.back());
  }
  // A little slack for rounding in the bounds.
  for (double& r : impl_->triangle_cover) r = r * (1.0 + 1e-9) + 1e-12;
  impl_->cover = cover * (1.0 + 1e-9) + 1e-12;
  Eigen::Matrix3Xd seeds(3, static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) {
    seeds.col(static_cast<Eigen::Index>(i)) = points[i];
  }
  impl_->seeds = std::make_unique<KdTree3>(seeds);
}

TriangleSurface3::~TriangleSurface3() = default;
TriangleSurface3::TriangleSurface3(TriangleSurface3&&) noexcept = default;
TriangleSurface3& TriangleSurface3::operator=(TriangleSurface3&&) noexcept = default;

int TriangleSurface3::NumTriangles() const { return static_cast<int>(impl_->a.cols()); }
int TriangleSurface3::NumSeeds() const { return impl_->seeds->NumPoints(); }
double TriangleSurface3::SeedCover() const { return impl_->cover; }

void TriangleSurface3::Closest(const Eigen::Matrix3Xd& queries, Eigen::Matrix3Xd* closest_points,
                               Eigen::VectorXd* squared_distances, int* num_radius_searches) const {
  const int n = static_cast<int>(queries.cols());
  closest_points->resize(3, n);
  squared_distances->resize(n);
  Eigen::MatrixXi nearest;
  Eigen::MatrixXd nearest_sq;
  impl_->seeds->NearestK(queries, kFirstSeeds, &nearest, &nearest_sq);
  const double cover = impl_->cover;
  std::vector<char> searched(static_cast<std::size_t>(n), 0);
  ParallelFor(n, [&](int begin, int end) {
    std::vector<int> within;
    std::vector<double> within_sq;
    for (int i = begin; i < end; ++i) {
      const Eigen::Vector3d q = queries.col(i);
      double best_sq = std::numeric_limits<double>::infinity();
      Eigen::Vector3d best = q;
      auto consider = [&](int seed) {
        const int t = impl_->seed_triangle[static_cast<std::size_t>(seed)];
        const Eigen::Vector3d x =
            ClosestPointOnTriangle(q, impl_->a.col(t), impl_->b.col(t), impl_->c.col(t));
        const double d = (x - q).squaredNorm();
        if (d < best_sq) {
          best_sq = d;
          best = x;
        }
      };
      int found = 0;
      for (Eigen::Index j = 0; j < nearest.rows() && nearest(j, i) >= 0; ++j, ++found) {
        consider(nearest(j, i));
      }
      // Certificate: a triangle closer than `best` has a seed within
      // best + cover of q. If the last of the found seeds is at least that
      // far (or every seed was found), they include such a seed.
      const double radius = std::sqrt(best_sq) + cover;
      const bool all_found = found == impl_->seeds->NumPoints();
      if (!all_found && std::sqrt(nearest_sq(found - 1, i)) < radius) {
        impl_->seeds->WithinRadius(q, radius, &within, &within_sq);
        for (std::size_t k = 0; k < within.size(); ++k) {
          // Triangle t is at least |q - seed| - cover(t) away: skip it when
          // that is not below the best distance so far.
          const int t = impl_->seed_triangle[static_cast<std::size_t>(within[k])];
          const double lower =
              std::sqrt(within_sq[k]) - impl_->triangle_cover[static_cast<std::size_t>(t)];
          if (lower > 0.0 && lower * lower >= best_sq) continue;
          consider(within[k]);
        }
        searched[static_cast<std::size_t>(i)] = 1;
      }
      closest_points->col(i) = best;
      (*squared_distances)(i) = best_sq;
    }
  });
  if (num_radius_searches != nullptr) {
    *num_radius_searches = static_cast<int>(std::count(searched.begin(), searched.end(), 1));
  }
}

void TriangleSurface3::ClosestBruteForce(const Eigen::Matrix3Xd& queries,
                                         Eigen::Matrix3Xd* closest_points,
                                         Eigen::VectorXd* squared_distances) const {
  const int n = static_cast<int>(queries.cols());
  closest_points->resize(3, n);
  squared_distances->resize(n);
  ParallelFor(n, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const Eigen::Vector3d q = queries.col(i);
      double best_sq = std::numeric_limits<double>::infinity();
      Eigen::Vector3d best = q;
      for (Eigen::Index t = 0; t < impl_->a.cols(); ++t) {
        const Eigen::Vector3d x =
            ClosestPointOnTriangle(q, impl_->a.col(t), impl_->b.col(t), impl_->c.col(t));
        const double d = (x - q).squaredNorm();
        if (d < best_sq) {
          best_sq = d;
          best = x;
        }
      }
      closest_points->col(i) = best;
      (*squared_distances)(i) = best_sq;
    }
  });
}

}  // namespace banmo
