#include "banmo/extract/marching_cubes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

// Cell corners: index c = x + 2 y + 4 z with x, y, z in {0, 1}.
// Cell edges: id = 4 * axis + b, where the two other axes (in increasing
// order) take the bits b & 1 and b >> 1; the edge runs from the corner with
// that axis bit 0 to the corner with it 1.
constexpr int kNumEdges = 12;

struct EdgeCorners {
  int a, b;
};

EdgeCorners CornersOfEdge(int edge) {
  const int axis = edge / 4;
  const int bits = edge % 4;
  const int o0 = axis == 0 ? 1 : 0;
  const int o1 = axis == 2 ? 1 : 2;
  const int a = ((bits & 1) << o0) | ((bits >> 1) << o1);
  return {a, a | (1 << axis)};
}

// Triangles (as cell-edge ids, counter-clockwise seen from outside) of each
// of the 256 inside/outside configurations (bit c set = corner c inside).
struct CaseTable {
  std::array<std::vector<std::array<int, 3>>, 256> triangles;
};

CaseTable BuildCaseTable() {
  int edge_of[8][8];
  for (auto& row : edge_of) std::fill(row, row + 8, -1);
  for (int e = 0; e < kNumEdges; ++e) {
    const EdgeCorners ec = CornersOfEdge(e);
    edge_of[ec.a][ec.b] = edge_of[ec.b][ec.a] = e;
  }
  // The six faces, corners counter-clockwise about the outward normal:
  // (u, v) = (axis + 1, axis + 2) mod 3 is right-handed about +axis.
  std::array<std::array<int, 4>, 6> faces;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      const int base = side << axis;
      std::array<int, 4> ccw = {base, base | (1 << u), base | (1 << u) | (1 << v), base | (1 << v)};
      if (side == 0) std::swap(ccw[1], ccw[3]);  // normal -axis: reverse the cycle
      faces[2 * axis + side] = ccw;
    }
  }
  // Faces (bit f) containing each edge.
  std::array<int, kNumEdges> edge_faces{};
  for (int f = 0; f < 6; ++f) {
    for (int i = 0; i < 4; ++i) {
      edge_faces[edge_of[faces[f][i]][faces[f][(i + 1) % 4]]] |= 1 << f;
    }
  }
  CaseTable table;
  for (int config = 0; config < 256; ++config) {
    std::array<int, kNumEdges> next;
    next.fill(-1);
    std::array<int, kNumEdges> num_in{};
    for (const auto& f : faces) {
      bool inside[4];
      for (int i = 0; i < 4; ++i) inside[i] = (config >> f[i]) & 1;
      // Each run of inside corners along the face cycle (an isolated corner
      // on an ambiguous face is its own run) gets one segment, from the edge
      // entering the run to the edge leaving it. With the cycle
      // counter-clockwise about the outward normal, this orients the loops so
      // that their fans face the outside (verified by the tests).
      for (int i = 0; i < 4; ++i) {
        if (inside[i] || !inside[(i + 1) % 4]) continue;
        const int enter = edge_of[f[i]][f[(i + 1) % 4]];
        int j = (i + 1) % 4;
        while (inside[(j + 1) % 4]) j = (j + 1) % 4;
        const int leave = edge_of[f[j]][f[(j + 1) % 4]];
        CHECK_EQ(next[enter], -1) << "config " << config;
        next[enter] = leave;
        ++num_in[leave];
      }
    }
    std::array<bool, kNumEdges> used{};
    for (int e = 0; e < kNumEdges; ++e) {
      const EdgeCorners ec = CornersOfEdge(e);
      const bool cut = ((config >> ec.a) & 1) != ((config >> ec.b) & 1);
      CHECK_EQ(cut, next[e] >= 0) << "config " << config << " edge " << e;
      CHECK_EQ(cut ? 1 : 0, num_in[e]) << "config " << config << " edge " << e;
      if (!cut || used[e]) continue;
      std::vector<int> loop;
      for (int x = e; !used[x]; x = next[x]) {
        used[x] = true;
        loop.push_back(x);
      }
      CHECK_GE(loop.size(), 3u);
      // Fan from an apex whose diagonals never join two vertices of one cell
      // face: such a diagonal would lie in that face, and the neighbour cell
      // could use the same vertex pair, giving an edge of four triangles.
      const int m = static_cast<int>(loop.size());
      int apex = -1;
      for (int r = 0; r < m && apex < 0; ++r) {
        bool ok = true;
        for (int i = 2; i + 1 < m && ok; ++i) {
          ok = (edge_faces[loop[r]] & edge_faces[loop[(r + i) % m]]) == 0;
        }
        if (ok) apex = r;
      }
      CHECK_GE(apex, 0) << "config " << config << ": no valid fan apex";
      for (int i = 1; i + 1 < m; ++i) {
        table.triangles[config].push_back(
            {loop[apex], loop[(apex + i) % m], loop[(apex + i + 1) % m]});
      }
    }
  }
  return table;
}

const CaseTable& GetCaseTable() {
  static const CaseTable table = BuildCaseTable();
  return table;
}

// Grid-edge vertex ids of one z-level of nodes: x-edges (cx * ny1) and
// y-edges (nx1 * cy); -1 where the edge is not cut.
struct LevelEdges {
  std::vector<int> x, y;
};

// The field at the columns of points, in batches of at most max_batch
// points; throws InputError on a non-finite value.
Eigen::VectorXd EvaluateField(const FieldBatchFunction& field, const Eigen::Matrix3Xd& points,
                              int max_batch) {
  const int n = static_cast<int>(points.cols());
  Eigen::VectorXd out(n);
  const int num_chunks = (n + max_batch - 1) / max_batch;
  const int chunk = num_chunks == 0 ? 0 : (n + num_chunks - 1) / num_chunks;
  Eigen::Matrix3Xd batch;
  Eigen::VectorXd values;
  for (int begin = 0; begin < n; begin += chunk) {
    const int m = std::min(n - begin, chunk);
    batch = points.middleCols(begin, m);
    values.resize(0);
    field(batch, &values);
    CHECK_EQ(values.size(), m) << "field callback returned the wrong number of values";
    for (int q = 0; q < m; ++q) {
      if (!std::isfinite(values[q])) {
        ThrowInputError("marching cubes: the field is not finite (", values[q], ") at point (",
                        batch.col(q).transpose(), "); are the model parameters finite?");
      }
    }
    out.segment(begin, m) = values;
  }
  return out;
}

// The fine grid of one MarchingCubes call: cx x cy x cz cells, nodes
// (i, j, k) with i in 0..cx etc., a z-level holding nx1 * ny1 nodes.
struct FineGrid {
  FineGrid(const GridShape& grid_shape, const GridOptions& options)
      : shape(grid_shape),
        origin(options.bounds_min),
        cx(shape.cells.x()),
        cy(shape.cells.y()),
        cz(shape.cells.z()),
        nx1(cx + 1),
        ny1(cy + 1),
        pad(options.close_at_bounds) {}

  Eigen::Vector3d NodePosition(int i, int j, int k) const {
    return Eigen::Vector3d(origin.x() + i * shape.spacing.x(), origin.y() + j * shape.spacing.y(),
                           origin.z() + k * shape.spacing.z());
  }
  // True for the boundary nodes that close_at_bounds sets outside.
  bool Padded(int i, int j, int k) const {
    return pad && (i == 0 || j == 0 || k == 0 || i == cx || j == cy || k == cz);
  }

  GridShape shape;
  Eigen::Vector3d origin;
  int cx, cy, cz, nx1, ny1;
  bool pad;
};

// The coarse pass (coarse_stride s > 1): the field at every s-th node per
// axis (plus the last node), and the blocks of the coarse grid that may hold
// the level set (the band). Fine nodes outside the band take the coarse
// values' trilinear interpolation: only their sign matters, and all corners
// of their blocks share it.
class CoarseBand {
 public:
  CoarseBand(const FineGrid& grid, int stride) : grid_(grid), s_(stride) {
    for (int a = 0; a < 3; ++a) {
      for (int i = 0; i < grid.shape.cells[a]; i += s_) nodes_[a].push_back(i);
      nodes_[a].push_back(grid.shape.cells[a]);
    }
    ncx_ = static_cast<int>(nodes_[0].size());
    ncy_ = static_cast<int>(nodes_[1].size());
    ncz_ = static_cast<int>(nodes_[2].size());
  }

  // Evaluates the field at the coarse nodes and marks the band blocks.
  void Evaluate(const FieldBatchFunction& field, const GridOptions& options, double outside_value) {
    const double iso = options.iso_level;
    coarse_.assign(static_cast<size_t>(ncx_) * ncy_ * ncz_, outside_value);
    std::vector<std::array<int, 3>> query;
    for (int c = 0; c < ncz_; ++c) {
      for (int b = 0; b < ncy_; ++b) {
        for (int a = 0; a < ncx_; ++a) {
          if (!grid_.Padded(nodes_[0][a], nodes_[1][b], nodes_[2][c])) query.push_back({a, b, c});
        }
      }
    }
    Eigen::Matrix3Xd coarse_points(3, static_cast<Eigen::Index>(query.size()));
    for (size_t q = 0; q < query.size(); ++q) {
      coarse_points.col(q) = grid_.NodePosition(nodes_[0][query[q][0]], nodes_[1][query[q][1]],
                                                nodes_[2][query[q][2]]);
    }
    const Eigen::VectorXd coarse_values =
        EvaluateField(field, coarse_points, options.max_batch_points);
    for (size_t q = 0; q < query.size(); ++q) {
      coarse_[(query[q][2] * ncy_ + query[q][1]) * ncx_ + query[q][0]] = coarse_values[q];
    }
    const double diagonal = s_ * grid_.shape.spacing.norm();
    const double margin = options.band * diagonal;
    band_.assign(static_cast<size_t>(ncx_ - 1) * (ncy_ - 1) * (ncz_ - 1), 0);
    for (int c = 0; c + 1 < ncz_; ++c) {
      for (int b = 0; b + 1 < ncy_; ++b) {
        for (int a = 0; a + 1 < ncx_; ++a) {
          int num_inside = 0;
          double min_distance = std::numeric_limits<double>::infinity();
          for (int corner = 0; corner < 8; ++corner) {
            const int ca = a + (corner & 1), cb = b + ((corner >> 1) & 1), cc = c + (corner >> 2);
            const double f = At(ca, cb, cc);
            num_inside += f < iso ? 1 : 0;
            // Padded corners hold a constant, not the field: only their sign
            // counts (as for the fine padded nodes).
            if (!grid_.Padded(nodes_[0][ca], nodes_[1][cb], nodes_[2][cc])) {
              min_distance = std::min(min_distance, std::abs(f - iso));
            }
          }
          band_[(c * (ncy_ - 1) + b) * (ncx_ - 1) + a] =
              (num_inside > 0 && num_inside < 8) || min_distance < margin;
        }
      }
    }
  }

  // True when fine node (i, j, k) lies in some band block.
  bool InBand(int i, int j, int k) const {
    const int bi = BlockOf(0, i), bj = BlockOf(1, j), bk = BlockOf(2, k);
    for (int dk = (k == nodes_[2][bk] && bk > 0) ? -1 : 0; dk <= 0; ++dk) {
      for (int dj = (j == nodes_[1][bj] && bj > 0) ? -1 : 0; dj <= 0; ++dj) {
        for (int di = (i == nodes_[0][bi] && bi > 0) ? -1 : 0; di <= 0; ++di) {
          if (band_[((bk + dk) * (ncy_ - 1) + bj + dj) * (ncx_ - 1) + bi + di]) return true;
        }
      }
    }
    return false;
  }

  // Trilinear interpolation of the coarse values at fine node (i, j, k).
  double Interpolate(int i, int j, int k) const {
    const int bi = BlockOf(0, i), bj = BlockOf(1, j), bk = BlockOf(2, k);
    const double u = double(i - nodes_[0][bi]) / (nodes_[0][bi + 1] - nodes_[0][bi]);
    const double v = double(j - nodes_[1][bj]) / (nodes_[1][bj + 1] - nodes_[1][bj]);
    const double w = double(k - nodes_[2][bk]) / (nodes_[2][bk + 1] - nodes_[2][bk]);
    double f = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
      const int x = corner & 1, y = (corner >> 1) & 1, z = corner >> 2;
      f += (x ? u : 1 - u) * (y ? v : 1 - v) * (z ? w : 1 - w) * At(bi + x, bj + y, bk + z);
    }
    return f;
  }

  int64_t num_evaluated() const { return static_cast<int64_t>(coarse_.size()); }

 private:
  // Block index along axis a of fine node i: the block starting at or before
  // it (the last block for the last node).
  int BlockOf(int a, int i) const {
    const int nb = static_cast<int>(nodes_[a].size()) - 1;
    return std::min(i / s_, nb - 1);
  }
  double At(int a, int b, int c) const { return coarse_[(c * ncy_ + b) * ncx_ + a]; }

  const FineGrid& grid_;
  int s_;
  std::array<std::vector<int>, 3> nodes_;  // fine indices of the coarse nodes per axis
  int ncx_ = 0, ncy_ = 0, ncz_ = 0;
  std::vector<double> coarse_;
  std::vector<char> band_;  // per block (ncx-1)(ncy-1)(ncz-1)
};

// The sweep through the z-levels of the fine grid: field values per level,
// one vertex per cut grid edge, triangles per cell from the case table.
class LevelSweep {
 public:
  LevelSweep(const FineGrid& grid, const CoarseBand& coarse, const FieldBatchFunction& field,
             const GridOptions& options, double outside_value)
      : grid_(grid),
        coarse_(coarse),
        field_(field),
        options_(options),
        iso_(options.iso_level),
        outside_value_(outside_value) {}

  // Field values of z-level k (nx1 * ny1, index j * nx1 + i).
  void EvaluateLevel(int k, std::vector<double>* level) {
    const int nx1 = grid_.nx1, ny1 = grid_.ny1;
    level->assign(static_cast<size_t>(nx1) * ny1, outside_value_);
    query_index_.clear();
    for (int j = 0; j < ny1; ++j) {
      for (int i = 0; i < nx1; ++i) {
        if (grid_.Padded(i, j, k)) continue;
        if (options_.coarse_stride > 1 && !coarse_.InBand(i, j, k)) {
          (*level)[j * nx1 + i] = coarse_.Interpolate(i, j, k);
          continue;
        }
        query_index_.push_back(j * nx1 + i);
      }
    }
    points_.resize(3, static_cast<Eigen::Index>(query_index_.size()));
    for (size_t q = 0; q < query_index_.size(); ++q) {
      points_.col(q) = grid_.NodePosition(query_index_[q] % nx1, query_index_[q] / nx1, k);
    }
    const Eigen::VectorXd values = EvaluateField(field_, points_, options_.max_batch_points);
    for (size_t q = 0; q < query_index_.size(); ++q) (*level)[query_index_[q]] = values[q];
    num_evaluated_ += static_cast<int64_t>(query_index_.size());
  }

  // The vertices on the cut x- and y-edges of z-level k (values f).
  void CutLevelEdges(int k, const std::vector<double>& f, LevelEdges* edges) {
    const int cx = grid_.cx, cy = grid_.cy, nx1 = grid_.nx1, ny1 = grid_.ny1;
    edges->x.assign(static_cast<size_t>(cx) * ny1, -1);
    edges->y.assign(static_cast<size_t>(nx1) * cy, -1);
    for (int j = 0; j < ny1; ++j) {
      for (int i = 0; i < cx; ++i) {
        const double fa = f[j * nx1 + i], fb = f[j * nx1 + i + 1];
        if ((fa < iso_) != (fb < iso_)) {
          edges->x[j * cx + i] =
              AddVertex(grid_.NodePosition(i, j, k), fa, grid_.NodePosition(i + 1, j, k), fb);
        }
      }
    }
    for (int j = 0; j < cy; ++j) {
      for (int i = 0; i < nx1; ++i) {
        const double fa = f[j * nx1 + i], fb = f[(j + 1) * nx1 + i];
        if ((fa < iso_) != (fb < iso_)) {
          edges->y[j * nx1 + i] =
              AddVertex(grid_.NodePosition(i, j, k), fa, grid_.NodePosition(i, j + 1, k), fb);
        }
      }
    }
  }

  // The vertices on the cut z-edges between z-levels k (lo) and k + 1 (hi).
  void CutZEdges(int k, const std::vector<double>& lo, const std::vector<double>& hi,
                 std::vector<int>* z_edges) {
    const int nx1 = grid_.nx1, ny1 = grid_.ny1;
    z_edges->assign(static_cast<size_t>(nx1) * ny1, -1);
    for (int j = 0; j < ny1; ++j) {
      for (int i = 0; i < nx1; ++i) {
        const double fa = lo[j * nx1 + i], fb = hi[j * nx1 + i];
        if ((fa < iso_) != (fb < iso_)) {
          (*z_edges)[j * nx1 + i] =
              AddVertex(grid_.NodePosition(i, j, k), fa, grid_.NodePosition(i, j, k + 1), fb);
        }
      }
    }
  }

  // The triangles of cell (i, j) between the levels lo and hi.
  void AddCellTriangles(const CaseTable& table, int i, int j, const std::vector<double>& lo,
                        const std::vector<double>& hi, const LevelEdges& lo_edges,
                        const LevelEdges& hi_edges, const std::vector<int>& z_edges) {
    const int cx = grid_.cx, nx1 = grid_.nx1;
    const std::vector<double>* level_values[2] = {&lo, &hi};
    const LevelEdges* level_edge_ids[2] = {&lo_edges, &hi_edges};
    int config = 0;
    for (int c = 0; c < 8; ++c) {
      const int x = c & 1, y = (c >> 1) & 1, z = c >> 2;
      if ((*level_values[z])[(j + y) * nx1 + i + x] < iso_) config |= 1 << c;
    }
    if (config == 0 || config == 255) return;
    auto vertex_of_edge = [&](int edge) {
      const int axis = edge / 4, b0 = edge & 1, b1 = (edge >> 1) & 1;
      if (axis == 0) return level_edge_ids[b1]->x[(j + b0) * cx + i];
      if (axis == 1) return level_edge_ids[b1]->y[j * nx1 + i + b0];
      return z_edges[(j + b1) * nx1 + i + b0];
    };
    for (const auto& tri : table.triangles[config]) {
      Eigen::Vector3i face(vertex_of_edge(tri[0]), vertex_of_edge(tri[1]), vertex_of_edge(tri[2]));
      DCHECK((face.array() >= 0).all());
      faces_.push_back(face);
    }
  }

  int64_t num_evaluated() const { return num_evaluated_; }

  TriangleMesh Mesh() const {
    TriangleMesh mesh;
    mesh.vertices.resize(3, static_cast<Eigen::Index>(vertices_.size()));
    for (size_t v = 0; v < vertices_.size(); ++v) mesh.vertices.col(v) = vertices_[v];
    mesh.faces.resize(3, static_cast<Eigen::Index>(faces_.size()));
    for (size_t f = 0; f < faces_.size(); ++f) mesh.faces.col(f) = faces_[f];
    return mesh;
  }

 private:
  int AddVertex(const Eigen::Vector3d& pa, double fa, const Eigen::Vector3d& pb, double fb) {
    // Cut edge: exactly one of fa, fb is < iso, so fb - fa != 0.
    const double t = std::clamp((iso_ - fa) / (fb - fa), 0.0, 1.0);
    vertices_.push_back(pa + t * (pb - pa));
    return static_cast<int>(vertices_.size()) - 1;
  }

  const FineGrid& grid_;
  const CoarseBand& coarse_;
  const FieldBatchFunction& field_;
  const GridOptions& options_;
  const double iso_, outside_value_;
  int64_t num_evaluated_ = 0;
  std::vector<int> query_index_;
  Eigen::Matrix3Xd points_;
  std::vector<Eigen::Vector3d> vertices_;
  std::vector<Eigen::Vector3i> faces_;
};

}  // namespace

void GridOptions::Check(const char* prefix) const {
  if (resolution < 2 || resolution > 4096) {
    ThrowInputError(prefix, ".resolution: expected 2..4096, got ", resolution);
  }
  if (!bounds_min.allFinite() || !bounds_max.allFinite() ||
      !(bounds_max.array() > bounds_min.array()).all()) {
    ThrowInputError(prefix,
                    ".bounds: expected finite bounds with max > min on every axis, got min (",
                    bounds_min.transpose(), ") max (", bounds_max.transpose(), ")");
  }
  if (!std::isfinite(iso_level)) ThrowInputError(prefix, ".iso_level: expected a finite value");
  if (coarse_stride < 1 || coarse_stride > 64) {
    ThrowInputError(prefix, ".coarse_stride: expected 1..64, got ", coarse_stride);
  }
  if (!(band >= 0) || !std::isfinite(band)) {
    ThrowInputError(prefix, ".band: expected a finite value >= 0, got ", band);
  }
  if (max_batch_points < 1) {
    ThrowInputError(prefix, ".max_batch_points: expected >= 1, got ", max_batch_points);
  }
}

GridShape ComputeGridShape(const GridOptions& options) {
  const Eigen::Vector3d extent = options.bounds_max - options.bounds_min;
  const double h = extent.maxCoeff() / options.resolution;
  GridShape shape;
  for (int a = 0; a < 3; ++a) {
    shape.cells[a] = std::max(1, static_cast<int>(std::lround(extent[a] / h)));
    shape.spacing[a] = extent[a] / shape.cells[a];
  }
  return shape;
}

TriangleMesh MarchingCubes(const FieldBatchFunction& field, const GridOptions& options,
                           MarchingCubesStats* stats) {
  options.Check();
  const CaseTable& table = GetCaseTable();
  const FineGrid grid(ComputeGridShape(options), options);
  const double outside_value = options.iso_level + grid.shape.spacing.minCoeff();
  CoarseBand coarse(grid, options.coarse_stride);
  if (options.coarse_stride > 1) coarse.Evaluate(field, options, outside_value);
  LevelSweep sweep(grid, coarse, field, options, outside_value);

  std::vector<double> lo, hi;
  LevelEdges lo_edges, hi_edges;
  std::vector<int> z_edges;
  sweep.EvaluateLevel(0, &lo);
  sweep.CutLevelEdges(0, lo, &lo_edges);
  for (int k = 0; k < grid.cz; ++k) {
    sweep.EvaluateLevel(k + 1, &hi);
    sweep.CutLevelEdges(k + 1, hi, &hi_edges);
    sweep.CutZEdges(k, lo, hi, &z_edges);
    for (int j = 0; j < grid.cy; ++j) {
      for (int i = 0; i < grid.cx; ++i) {
        sweep.AddCellTriangles(table, i, j, lo, hi, lo_edges, hi_edges, z_edges);
      }
    }
    std::swap(lo, hi);
    std::swap(lo_edges, hi_edges);
  }

  if (stats != nullptr) {
    stats->num_nodes = static_cast<int64_t>(grid.nx1) * grid.ny1 * (grid.cz + 1);
    stats->num_evaluated = sweep.num_evaluated() + coarse.num_evaluated();
  }
  return sweep.Mesh();
}

TriangleMesh RemoveUnreferencedVertices(const TriangleMesh& mesh) {
  std::vector<int> new_index(mesh.NumVertices(), -1);
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int k = 0; k < 3; ++k) new_index[mesh.faces(k, f)] = 0;
  }
  int count = 0;
  for (int& idx : new_index) {
    if (idx == 0) idx = count++;
  }
  TriangleMesh out;
  out.vertices.resize(3, count);
  if (mesh.HasColors()) out.colors.resize(3, count);
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    if (new_index[v] < 0) continue;
    out.vertices.col(new_index[v]) = mesh.vertices.col(v);
    if (mesh.HasColors()) out.colors.col(new_index[v]) = mesh.colors.col(v);
  }
  out.faces.resize(3, mesh.NumFaces());
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int k = 0; k < 3; ++k) out.faces(k, f) = new_index[mesh.faces(k, f)];
  }
  return out;
}

MeshStats ComputeMeshStats(const TriangleMesh& mesh) {
  MeshStats stats;
  stats.num_faces = mesh.NumFaces();
  // Directed edges keyed by (min, max) vertex; the direction flag says
  // whether the face traverses it as min -> max.
  struct HalfEdge {
    int64_t key;
    bool forward;
    int face;
  };
  std::vector<HalfEdge> half_edges;
  half_edges.reserve(3 * static_cast<size_t>(mesh.NumFaces()));
  const int64_t V = mesh.NumVertices();
  std::vector<bool> referenced(V, false);
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, f));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, f));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, f));
    stats.signed_volume += a.dot(b.cross(c)) / 6.0;
    stats.area += 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) {
      const int u = mesh.faces(k, f), w = mesh.faces((k + 1) % 3, f);
      referenced[u] = true;
      half_edges.push_back({std::min<int64_t>(u, w) * V + std::max<int64_t>(u, w), u < w, f});
    }
  }
  std::sort(half_edges.begin(), half_edges.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.key != y.key ? x.key < y.key : x.face < y.face;
  });
  // Union-find over faces through shared edges.
  std::vector<int> parent(mesh.NumFaces());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (size_t i = 0; i < half_edges.size();) {
    size_t j = i;
    int forward = 0;
    while (j < half_edges.size() && half_edges[j].key == half_edges[i].key) {
      forward += half_edges[j].forward ? 1 : 0;
      const int r1 = find(half_edges[i].face), r2 = find(half_edges[j].face);
      if (r1 != r2) parent[std::max(r1, r2)] = std::min(r1, r2);
      ++j;
    }
    const int uses = static_cast<int>(j - i);
    ++stats.num_edges;
    if (uses == 1) ++stats.num_boundary_edges;
    if (uses > 2) ++stats.num_nonmanifold_edges;
    if (uses == 2 && forward != 1) ++stats.num_inconsistent_edges;
    i = j;
  }
  for (int f = 0; f < mesh.NumFaces(); ++f) stats.num_components += find(f) == f ? 1 : 0;
  stats.num_vertices = static_cast<int>(std::count(referenced.begin(), referenced.end(), true));
  stats.euler_characteristic = stats.num_vertices - stats.num_edges + stats.num_faces;
  return stats;
}

}  // namespace banmo
