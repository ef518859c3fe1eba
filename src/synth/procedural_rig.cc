#include "banmo/synth/procedural_rig.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"
#include "banmo/util/yaml.h"

namespace banmo::synth {

double EllipsoidSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& radii) {
  const double k0 = p.cwiseQuotient(radii).norm();
  const double k1 = p.cwiseQuotient(radii.cwiseProduct(radii)).norm();
  if (k1 == 0) return -radii.minCoeff();
  return k0 * (k0 - 1) / k1;
}

double CapsuleSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  double radius) {
  const Eigen::Vector3d ab = b - a, ap = p - a;
  const double len2 = ab.squaredNorm();
  const double h = len2 > 0 ? std::clamp(ap.dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (ap - h * ab).norm() - radius;
}

double SmoothMin(double a, double b, double k) {
  if (k <= 0) return std::min(a, b);
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}

TriangleMesh MeshLevelSet(const std::function<double(const Eigen::Vector3d&)>& sdf,
                          const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double cell_size,
                          int projection_steps) {
  CHECK_GT(cell_size, 0);
  Eigen::Vector3i n;
  for (int a = 0; a < 3; ++a) {
    n[a] = std::max(2, static_cast<int>(std::ceil((hi[a] - lo[a]) / cell_size)) + 1);
  }
  const Eigen::Vector3d step((hi - lo).array() / (n.cast<double>().array() - 1));
  auto point = [&](int i, int j, int k) {
    return Eigen::Vector3d(lo[0] + i * step[0], lo[1] + j * step[1], lo[2] + k * step[2]);
  };
  auto sample_index = [&](int i, int j, int k) {
    return (static_cast<size_t>(k) * n[1] + j) * n[0] + i;
  };
  std::vector<double> f(static_cast<size_t>(n[0]) * n[1] * n[2]);
  ParallelFor(n[2], [&](int begin, int end) {
    for (int k = begin; k < end; ++k) {
      for (int j = 0; j < n[1]; ++j) {
        for (int i = 0; i < n[0]; ++i) f[sample_index(i, j, k)] = sdf(point(i, j, k));
      }
    }
  });
  // Nudge exact zeros so every edge has a clear sign.
  for (double& v : f) {
    if (v == 0) v = 1e-12;
  }
  // One vertex per cell with a sign change: mean of its edge crossings.
  const Eigen::Vector3i nc = n - Eigen::Vector3i::Ones();
  auto cell_index = [&](int i, int j, int k) {
    return (static_cast<size_t>(k) * nc[1] + j) * nc[0] + i;
  };
  std::vector<int> cell_vertex(static_cast<size_t>(nc[0]) * nc[1] * nc[2], -1);
  std::vector<Eigen::Vector3d> verts;
  static const int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0},
                                    {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
  static const int kEdge[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                   {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  for (int k = 0; k < nc[2]; ++k) {
    for (int j = 0; j < nc[1]; ++j) {
      for (int i = 0; i < nc[0]; ++i) {
        double v[8];
        int inside = 0;
        for (int c = 0; c < 8; ++c) {
          v[c] = f[sample_index(i + kCorner[c][0], j + kCorner[c][1], k + kCorner[c][2])];
          inside += v[c] < 0;
        }
        if (inside == 0 || inside == 8) continue;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        int count = 0;
        for (const auto& e : kEdge) {
          const double a = v[e[0]], b = v[e[1]];
          if ((a < 0) == (b < 0)) continue;
          const double s = a / (a - b);
          const Eigen::Vector3d pa =
              point(i + kCorner[e[0]][0], j + kCorner[e[0]][1], k + kCorner[e[0]][2]);
          const Eigen::Vector3d pb =
              point(i + kCorner[e[1]][0], j + kCorner[e[1]][1], k + kCorner[e[1]][2]);
          sum += pa + s * (pb - pa);
          ++count;
        }
        cell_vertex[cell_index(i, j, k)] = static_cast<int>(verts.size());
        verts.push_back(sum / count);
      }
    }
  }
  // One quad per grid edge with a sign change, joining the 4 cells around it.
  std::vector<Eigen::Vector3i> faces;
  for (int k = 0; k < n[2]; ++k) {
    for (int j = 0; j < n[1]; ++j) {
      for (int i = 0; i < n[0]; ++i) {
        const double f0 = f[sample_index(i, j, k)];
        for (int axis = 0; axis < 3; ++axis) {
          int q[3] = {i, j, k};
          ++q[axis];
          if (q[axis] >= n[axis]) continue;
          const double f1 = f[sample_index(q[0], q[1], q[2])];
          if ((f0 < 0) == (f1 < 0)) continue;
          // The two other axes; the 4 cells are offset by 0/-1 along them.
          const int u = (axis + 1) % 3, w = (axis + 2) % 3;
          int ids[4];
          bool ok = true;
          static const int kOff[4][2] = {{-1, -1}, {0, -1}, {0, 0}, {-1, 0}};
          for (int c = 0; c < 4 && ok; ++c) {
            int cidx[3] = {i, j, k};
            cidx[u] += kOff[c][0];
            cidx[w] += kOff[c][1];
            for (int a = 0; a < 3; ++a) ok = ok && cidx[a] >= 0 && cidx[a] < nc[a];
            if (ok) ids[c] = cell_vertex[cell_index(cidx[0], cidx[1], cidx[2])];
            ok = ok && ids[c] >= 0;
          }
          if (!ok) continue;
          // Outward direction along `axis`: from inside to outside.
          const double outward = f0 < 0 ? 1.0 : -1.0;
          const Eigen::Vector3d nq =
              (verts[ids[2]] - verts[ids[0]]).cross(verts[ids[3]] - verts[ids[1]]);
          if (nq[axis] * outward < 0) std::swap(ids[1], ids[3]);
          faces.emplace_back(ids[0], ids[1], ids[2]);
          faces.emplace_back(ids[0], ids[2], ids[3]);
        }
      }
    }
  }
  // Project vertices onto the level set (Newton steps along the gradient).
  const double h = 1e-3 * cell_size;
  ParallelFor(static_cast<int>(verts.size()), [&](int begin, int end) {
    for (int vi = begin; vi < end; ++vi) {
      Eigen::Vector3d& p = verts[vi];
      for (int it = 0; it < projection_steps; ++it) {
        const double d = sdf(p);
        Eigen::Vector3d g;
        for (int a = 0; a < 3; ++a) {
          Eigen::Vector3d e = Eigen::Vector3d::Zero();
          e[a] = h;
          g[a] = (sdf(p + e) - sdf(p - e)) / (2 * h);
        }
        const double g2 = g.squaredNorm();
        if (g2 < 1e-12) break;
        Eigen::Vector3d delta = d * g / g2;
        // Never move a vertex out of its neighbourhood (thin parts).
        const double len = delta.norm();
        if (len > 0.5 * cell_size) delta *= 0.5 * cell_size / len;
        p -= delta;
      }
    }
  });
  TriangleMesh mesh;
  mesh.vertices.resize(3, verts.size());
  for (size_t i = 0; i < verts.size(); ++i) mesh.vertices.col(i) = verts[i];
  mesh.faces.resize(3, faces.size());
  for (size_t i = 0; i < faces.size(); ++i) mesh.faces.col(i) = faces[i];
  return mesh;
}

namespace {

struct Shape {
  int joint = 0;
  bool capsule = false;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // ellipsoid
  Eigen::Vector3d radii = Eigen::Vector3d::Ones();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();  // ellipsoid frame (columns) in rig space
  Eigen::Vector3d from = Eigen::Vector3d::Zero(), to = Eigen::Vector3d::Zero();  // capsule
  double radius = 0;
  Eigen::Vector3d color = Eigen::Vector3d::Constant(0.7);

  double Sdf(const Eigen::Vector3d& p) const {
    if (capsule) return CapsuleSdf(p, from, to, radius);
    return EllipsoidSdf(axes.transpose() * (p - center), radii);
  }
  Eigen::Vector3d Lo() const {
    if (capsule) return from.cwiseMin(to) - Eigen::Vector3d::Constant(radius);
    return center - Eigen::Vector3d::Constant(radii.maxCoeff());
  }
  Eigen::Vector3d Hi() const {
    if (capsule) return from.cwiseMax(to) + Eigen::Vector3d::Constant(radius);
    return center + Eigen::Vector3d::Constant(radii.maxCoeff());
  }
};

// A sinusoidal motion term: rotation about `axis` by
// offset + amplitude * sin(2 pi (cycles t / duration + phase)), or a
// translation with vector amplitude and offset.
struct MotionTerm {
  int joint = 0;
  bool rotation = true;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();
  double offset = 0, amplitude = 0;                    // radians
  Eigen::Vector3d offset_t = Eigen::Vector3d::Zero();  // translation
  Eigen::Vector3d amplitude_t = Eigen::Vector3d::Zero();
  double phase = 0;
  int cycles = 1;
};

// The `mesh:` section: meshing and appearance settings.
struct MeshSettings {
  double cell_size = 0;
  double blend_radius = 0;
  double skin_blend = 0;
  double pattern_frequency = 0;
  double pattern_strength = 0;
};

MeshSettings ReadMeshSettings(const YamlNode& root) {
  const YamlNode mesh = root.Required("mesh");
  mesh.CheckKeys(
      {"cell_size", "blend_radius", "skin_blend", "pattern_frequency", "pattern_strength"});
  MeshSettings m;
  mesh.ReadRequired("cell_size", &m.cell_size);
  m.blend_radius = mesh.ValueOr("blend_radius", 0.0);
  m.skin_blend = mesh.ValueOr("skin_blend", 0.05);
  m.pattern_frequency = mesh.ValueOr("pattern_frequency", 4.0);
  m.pattern_strength = mesh.ValueOr("pattern_strength", 0.3);
  if (!(m.cell_size > 0)) mesh["cell_size"].Fail("expected > 0");
  if (m.blend_radius < 0) mesh["blend_radius"].Fail("expected >= 0");
  if (!(m.skin_blend > 0)) mesh["skin_blend"].Fail("expected > 0");
  if (m.pattern_strength < 0 || m.pattern_strength > 1) {
    mesh["pattern_strength"].Fail("expected [0, 1]");
  }
  return m;
}

// The `joints:` section: one node and one influence per joint (rest positions
// in rig space, identity rest rotations). Returns the joint index by name.
std::map<std::string, int> ReadJoints(const YamlNode& root, Rig* rig) {
  const YamlNode joints = root.Required("joints");
  if (joints.size() == 0) joints.TypeError("a non-empty list");
  std::map<std::string, int> joint_index;
  std::vector<Eigen::Vector3d> joint_position;
  for (size_t i = 0; i < joints.size(); ++i) {
    const YamlNode joint = joints[i];
    joint.CheckKeys({"name", "parent", "position"});
    RigNode node;
    joint.ReadRequired("name", &node.name);
    if (joint_index.count(node.name)) joint.Fail("duplicate joint name '", node.name, "'");
    const Eigen::Vector3d pos = joint.Required("position").As<Eigen::Vector3d>();
    if (!joint["parent"].IsNull()) {
      const std::string parent = joint["parent"].As<std::string>();
      auto it = joint_index.find(parent);
      if (it == joint_index.end()) {
        joint["parent"].Fail("unknown joint '", parent, "' (parents must come first)");
      }
      node.parent = it->second;
      node.translation = pos - joint_position[node.parent];
    } else {
      node.translation = pos;
    }
    joint_index[node.name] = static_cast<int>(rig->nodes.size());
    joint_position.push_back(pos);
    rig->nodes.push_back(node);
    RigInfluence inf;
    inf.node = static_cast<int>(rig->nodes.size()) - 1;
    inf.inverse_bind.topRightCorner<3, 1>() = -pos;
    rig->influences.push_back(inf);
  }
  return joint_index;
}

int FindJoint(const std::map<std::string, int>& joint_index, const YamlNode& node) {
  const std::string name = node.As<std::string>();
  auto it = joint_index.find(name);
  if (it == joint_index.end()) node.Fail("unknown joint '", name, "'");
  return it->second;
}

// One entry of `shapes:`: an ellipsoid or a capsule.
Shape ReadShape(const std::map<std::string, int>& joint_index, const YamlNode& s) {
  s.CheckKeys(
      {"joint", "type", "center", "radii", "rotation_deg", "from", "to", "radius", "color"});
  Shape shape;
  shape.joint = FindJoint(joint_index, s.Required("joint"));
  const std::string type = s.Required("type").As<std::string>();
  if (type == "ellipsoid") {
    s.ReadRequired("center", &shape.center);
    s.ReadRequired("radii", &shape.radii);
    if (!(shape.radii.minCoeff() > 0)) s["radii"].Fail("expected positive radii");
    const Eigen::Vector3d euler =
        s.ValueOr("rotation_deg", Eigen::Vector3d(Eigen::Vector3d::Zero())) * M_PI / 180;
    shape.axes = (Eigen::AngleAxisd(euler[2], Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(euler[1], Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(euler[0], Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
  } else if (type == "capsule") {
    shape.capsule = true;
    s.ReadRequired("from", &shape.from);
    s.ReadRequired("to", &shape.to);
    s.ReadRequired("radius", &shape.radius);
    if (!(shape.radius > 0)) s["radius"].Fail("expected > 0");
  } else {
    s["type"].Fail("expected 'ellipsoid' or 'capsule', found '", type, "'");
  }
  s.ReadIfPresent("color", &shape.color);
  if (shape.color.minCoeff() < 0 || shape.color.maxCoeff() > 1) {
    s["color"].Fail("expected values in [0, 1]");
  }
  return shape;
}

std::vector<Shape> ReadShapes(const YamlNode& root, const std::map<std::string, int>& joint_index) {
  const YamlNode list = root.Required("shapes");
  if (list.size() == 0) list.TypeError("a non-empty list");
  std::vector<Shape> shapes;
  for (size_t i = 0; i < list.size(); ++i) shapes.push_back(ReadShape(joint_index, list[i]));
  return shapes;
}

// The rest surface: the shapes' smooth union, meshed and projected onto its
// zero level set, into rig->rest_vertices and rig->faces.
void MeshShapes(const std::string& source, const std::vector<Shape>& shapes, const MeshSettings& m,
                Rig* rig) {
  const double blend = m.blend_radius, cell_size = m.cell_size;
  auto sdf = [&](const Eigen::Vector3d& p) {
    double d = shapes[0].Sdf(p);
    for (size_t i = 1; i < shapes.size(); ++i) d = SmoothMin(d, shapes[i].Sdf(p), blend);
    return d;
  };
  Eigen::Vector3d lo = shapes[0].Lo(), hi = shapes[0].Hi();
  for (const auto& s : shapes) lo = lo.cwiseMin(s.Lo()), hi = hi.cwiseMax(s.Hi());
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(2 * cell_size + blend);
  const double cells = ((hi - lo + 2 * margin) / cell_size).prod();
  if (cells > 4e7) {
    ThrowInputError(source, ": mesh.cell_size: too small for the shapes (", cells, " grid cells)");
  }
  TriangleMesh surface = MeshLevelSet(sdf, lo - margin, hi + margin, cell_size);
  if (surface.NumFaces() == 0) ThrowInputError(source, ": the shapes produce an empty surface");
  rig->rest_vertices = surface.vertices;
  rig->faces = surface.faces;
}

// Skinning of rest vertex i into rig->vertex_influences / vertex_weights: the
// 4 joints nearest by their shapes' SDF, softmax weights exp(-d / skin_blend).
// `dj` (per joint) and `ds` (per shape, the SDFs at the vertex, kept for the
// colour) and `order` are scratch; returns the smallest shape SDF.
double SkinVertex(const std::vector<Shape>& shapes, double skin_blend, int i,
                  std::vector<double>* dj, std::vector<double>* ds,
                  std::vector<std::pair<double, int>>* order, Rig* rig) {
  const int nj = static_cast<int>(rig->nodes.size());
  const Eigen::Vector3d p = rig->rest_vertices.col(i);
  std::fill(dj->begin(), dj->end(), std::numeric_limits<double>::infinity());
  double dmin = std::numeric_limits<double>::infinity();
  for (size_t s = 0; s < shapes.size(); ++s) {
    (*ds)[s] = shapes[s].Sdf(p);
    (*dj)[shapes[s].joint] = std::min((*dj)[shapes[s].joint], (*ds)[s]);
    dmin = std::min(dmin, (*ds)[s]);
  }
  for (int j = 0; j < nj; ++j) (*order)[j] = {std::exp(-((*dj)[j] - dmin) / skin_blend), j};
  std::partial_sort(order->begin(), order->begin() + std::min(4, nj), order->end(),
                    [](const auto& a, const auto& b) { return a.first > b.first; });
  double sum = 0;
  for (int k = 0; k < std::min(4, nj); ++k) sum += (*order)[k].first;
  for (int k = 0; k < std::min(4, nj); ++k) {
    rig->vertex_influences(k, i) = (*order)[k].second;
    rig->vertex_weights(k, i) = static_cast<float>((*order)[k].first / sum);
  }
  return dmin;
}

// Colour at rest point p: the shapes' colours blended with sharper weights
// than the skinning (ds: the shapes' SDFs at p, dmin their minimum), times a
// fixed sinusoidal pattern.
Eigen::Vector3d VertexColour(const std::vector<Shape>& shapes, const MeshSettings& m,
                             const Eigen::Vector3d& p, const std::vector<double>& ds, double dmin) {
  // Pattern directions (fixed): three per colour channel.
  const Eigen::Vector3d dirs[3] = {Eigen::Vector3d(0.8, 0.5, 0.3).normalized(),
                                   Eigen::Vector3d(-0.3, 0.9, 0.4).normalized(),
                                   Eigen::Vector3d(0.2, -0.4, 0.9).normalized()};
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  double csum = 0;
  for (size_t s = 0; s < shapes.size(); ++s) {
    const double w = std::exp(-(ds[s] - dmin) / (0.5 * m.skin_blend));
    c += w * shapes[s].color;
    csum += w;
  }
  c /= csum;
  for (int ch = 0; ch < 3; ++ch) {
    const double wave = std::sin(m.pattern_frequency * dirs[ch].dot(p) * 2 * M_PI + ch) *
                        std::cos(m.pattern_frequency * 0.7 * dirs[(ch + 1) % 3].dot(p) * 2 * M_PI);
    c[ch] = std::clamp(c[ch] * (1 - m.pattern_strength + m.pattern_strength * (0.5 + 0.5 * wave)) +
                           0.15 * m.pattern_strength * wave,
                       0.0, 1.0);
  }
  return c;
}

// Skin weights, vertex colours and the one material of the meshed rig.
void SkinAndColour(const std::vector<Shape>& shapes, const MeshSettings& m, Rig* rig) {
  const int nv = rig->NumVertices();
  rig->vertex_influences.setConstant(kMaxVertexInfluences, nv, -1);
  rig->vertex_weights.setZero(kMaxVertexInfluences, nv);
  rig->vertex_colors.resize(3, nv);
  const int nj = static_cast<int>(rig->nodes.size());
  ParallelFor(nv, [&](int begin, int end) {
    std::vector<double> dj(nj), ds(shapes.size());
    std::vector<std::pair<double, int>> order(nj);
    for (int i = begin; i < end; ++i) {
      const double dmin = SkinVertex(shapes, m.skin_blend, i, &dj, &ds, &order, rig);
      rig->vertex_colors.col(i) =
          VertexColour(shapes, m, rig->rest_vertices.col(i), ds, dmin).cast<float>();
    }
  });
  rig->face_material.assign(rig->NumFaces(), 0);
  rig->materials.push_back(RigMaterial{});
}

// One entry of `animation.channels:`.
MotionTerm ReadMotionTerm(const std::map<std::string, int>& joint_index, const YamlNode& c) {
  c.CheckKeys({"joint", "axis", "offset_deg", "amplitude_deg", "translation", "translation_offset",
               "phase", "cycles"});
  MotionTerm t;
  t.joint = FindJoint(joint_index, c.Required("joint"));
  t.phase = c.ValueOr("phase", 0.0);
  const double cycles = c.ValueOr("cycles", 1.0);
  t.cycles = static_cast<int>(cycles);
  if (t.cycles < 1 || t.cycles != cycles) c["cycles"].Fail("expected an integer >= 1 (loops)");
  const bool has_rot = c.Has("axis") || c.Has("amplitude_deg") || c.Has("offset_deg");
  const bool has_trans = c.Has("translation") || c.Has("translation_offset");
  if (has_rot == has_trans) c.Fail("expected either axis/amplitude_deg or translation");
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  if (has_rot) {
    c.ReadRequired("axis", &t.axis);
    if (!(t.axis.norm() > 0)) c["axis"].Fail("expected a non-zero vector");
    t.axis.normalize();
    t.offset = c.ValueOr("offset_deg", 0.0) * M_PI / 180;
    t.amplitude = c.ValueOr("amplitude_deg", 0.0) * M_PI / 180;
  } else {
    t.rotation = false;
    t.amplitude_t = c.ValueOr("translation", zero);
    t.offset_t = c.ValueOr("translation_offset", zero);
  }
  return t;
}

// Joint j's rotation and translation channels sampled at keys + 1 times over
// `duration` (only the channels its terms move are appended).
void SampleJointChannels(const std::vector<MotionTerm>& terms, const RigNode& node, int j,
                         double duration, int keys, Animation* animation) {
  bool rot = false, trans = false;
  for (const auto& t : terms) {
    if (t.joint != j) continue;
    rot = rot || t.rotation;
    trans = trans || !t.rotation;
  }
  if (!rot && !trans) return;
  AnimationChannel rc, tc;
  rc.node = tc.node = j;
  rc.path = ChannelPath::kRotation;
  tc.path = ChannelPath::kTranslation;
  rc.values.resize(4, keys + 1);
  tc.values.resize(3, keys + 1);
  for (int k = 0; k <= keys; ++k) {
    const double time = duration * k / keys;
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    Eigen::Vector3d tr = node.translation;
    for (const auto& t : terms) {
      if (t.joint != j) continue;
      const double s = std::sin(2 * M_PI * (t.cycles * time / duration + t.phase));
      if (t.rotation) {
        q = q * Eigen::Quaterniond(Eigen::AngleAxisd(t.offset + t.amplitude * s, t.axis));
      } else {
        tr += t.offset_t + t.amplitude_t * s;
      }
    }
    rc.times.push_back(time);
    tc.times.push_back(time);
    rc.values.col(k) << q.x(), q.y(), q.z(), q.w();
    tc.values.col(k) = tr;
  }
  if (rot) animation->channels.push_back(rc);
  if (trans) animation->channels.push_back(tc);
}

// The `animation:` section: sinusoidal motion terms sampled into keyframes.
Animation ReadAnimation(const YamlNode& root, const std::map<std::string, int>& joint_index,
                        const Rig& rig) {
  const YamlNode anim = root.Required("animation");
  anim.CheckKeys({"name", "duration", "keys", "channels"});
  Animation animation;
  anim.ReadRequired("name", &animation.name);
  const double duration = anim.Required("duration").As<double>();
  if (!(duration > 0)) anim["duration"].Fail("expected > 0");
  const double keys_d = anim.ValueOr("keys", 60.0);
  const int keys = static_cast<int>(keys_d);
  if (keys < 2 || keys != keys_d) anim["keys"].Fail("expected an integer >= 2");
  const YamlNode channels = anim.Required("channels");
  if (!channels.IsSequence()) channels.TypeError("a list");
  std::vector<MotionTerm> terms;
  for (size_t i = 0; i < channels.size(); ++i) {
    terms.push_back(ReadMotionTerm(joint_index, channels[i]));
  }
  for (int j = 0; j < static_cast<int>(rig.nodes.size()); ++j) {
    SampleJointChannels(terms, rig.nodes[j], j, duration, keys, &animation);
  }
  if (animation.channels.empty()) channels.Fail("expected at least one channel");
  return animation;
}

}  // namespace

Rig BuildProceduralRig(const std::string& yaml_text, const std::string& source) {
  const YamlNode root = YamlNode::Parse(yaml_text, source);
  root.CheckKeys({"name", "mesh", "joints", "shapes", "animation"});
  Rig rig;
  root.ReadRequired("name", &rig.name);
  const MeshSettings mesh = ReadMeshSettings(root);
  const std::map<std::string, int> joint_index = ReadJoints(root, &rig);
  const std::vector<Shape> shapes = ReadShapes(root, joint_index);
  MeshShapes(source, shapes, mesh, &rig);
  SkinAndColour(shapes, mesh, &rig);
  rig.animations.push_back(ReadAnimation(root, joint_index, rig));
  const std::string problem = rig.Validate();
  if (!problem.empty()) ThrowInputError(source, ": ", problem);
  return rig;
}

}  // namespace banmo::synth
