// CGAL is used only in this file and largest_component.cc (slow headers).
#include "banmo/extract/skeleton.h"

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/extract_mean_curvature_flow_skeleton.h>

#include <algorithm>
#include <cmath>

#include "banmo/deform/bone_centres.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Skeletonization = CGAL::Mean_curvature_flow_skeletonization<SurfaceMesh>;

}  // namespace

void CurveSkeleton(const TriangleMesh& mesh, Eigen::Matrix3Xd* from, Eigen::Matrix3Xd* to) {
  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> index(mesh.NumVertices());
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    const Eigen::Vector3d& p = mesh.vertices.col(i);
    index[i] = sm.add_vertex(Point(p.x(), p.y(), p.z()));
  }
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const auto face =
        sm.add_face(index[mesh.faces(0, f)], index[mesh.faces(1, f)], index[mesh.faces(2, f)]);
    if (face == SurfaceMesh::null_face()) {
      ThrowInputError("curve skeleton: face ", f, " makes the mesh non-manifold");
    }
  }
  if (sm.number_of_faces() == 0 || !CGAL::is_closed(sm)) {
    ThrowInputError("curve skeleton: the mesh (", mesh.NumFaces(), " faces) is not closed");
  }
  Skeletonization::Skeleton skeleton;
  CGAL::extract_mean_curvature_flow_skeleton(sm, skeleton);
  const int E = static_cast<int>(boost::num_edges(skeleton));
  from->resize(3, E);
  to->resize(3, E);
  int j = 0;
  for (const auto& e : CGAL::make_range(boost::edges(skeleton))) {
    const Point& a = skeleton[boost::source(e, skeleton)].point;
    const Point& b = skeleton[boost::target(e, skeleton)].point;
    from->col(j) = Eigen::Vector3d(a.x(), a.y(), a.z());
    to->col(j) = Eigen::Vector3d(b.x(), b.y(), b.z());
    ++j;
  }
}

std::vector<Eigen::Vector3d> BoneCentresFromSkeleton(const TriangleMesh& mesh, int num_bones,
                                                     uint32_t seed) {
  CHECK_GE(num_bones, 1);
  Eigen::Matrix3Xd from, to;
  CurveSkeleton(mesh, &from, &to);
  double length = 0.0;
  for (int j = 0; j < from.cols(); ++j) length += (to.col(j) - from.col(j)).norm();
  if (!(length > 0.0)) {
    ThrowInputError("curve skeleton: ", from.cols(), " edges of total length 0");
  }
  // Points at the midpoints of pieces of about length / (32 B), each
  // weighted by its piece's length: k-means then sees the curves' length.
  const double step = length / (32.0 * num_bones);
  std::vector<Eigen::Vector3d> points;
  std::vector<double> weights;
  for (int j = 0; j < from.cols(); ++j) {
    const Eigen::Vector3d d = to.col(j) - from.col(j);
    const double len = d.norm();
    if (!(len > 0.0)) continue;
    const int pieces = std::max(1, static_cast<int>(std::ceil(len / step)));
    for (int k = 0; k < pieces; ++k) {
      points.push_back(from.col(j) + d * ((k + 0.5) / pieces));
      weights.push_back(len / pieces);
    }
  }
  // CGAL's edge order is not deterministic (it follows addresses), the
  // k-means seeding is: sort the points (with their weights) first.
  std::vector<int> order(points.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const Eigen::Vector3d& pa = points[a];
    const Eigen::Vector3d& pb = points[b];
    return std::lexicographical_compare(pa.data(), pa.data() + 3, pb.data(), pb.data() + 3);
  });
  const int n = static_cast<int>(points.size());
  if (n < num_bones) {
    ThrowInputError("curve skeleton: ", n, " points along it, fewer than the ", num_bones,
                    " bones");
  }
  Eigen::Matrix3Xd p(3, n);
  Eigen::VectorXd w(n);
  for (int i = 0; i < n; ++i) {
    p.col(i) = points[order[i]];
    w[i] = weights[order[i]];
  }
  return WeightedKMeans(p, w, num_bones, seed);
}

}  // namespace banmo
