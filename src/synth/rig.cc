#include "banmo/synth/rig.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>

#include "banmo/util/logging.h"

namespace banmo::synth {

int Rig::FindAnimation(const std::string& name) const {
  for (size_t i = 0; i < animations.size(); ++i) {
    if (animations[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

std::string Rig::Validate() const {
  std::ostringstream os;
  const int num_nodes = static_cast<int>(nodes.size());
  const int v = NumVertices();
  for (int n = 0; n < num_nodes; ++n) {
    if (nodes[n].parent < -1 || nodes[n].parent >= num_nodes || nodes[n].parent == n) {
      os << "node " << n << " has an invalid parent " << nodes[n].parent;
      return os.str();
    }
  }
  // Cycles: walking up from any node must end within num_nodes steps.
  for (int n = 0; n < num_nodes; ++n) {
    int p = n, steps = 0;
    while (p >= 0 && steps <= num_nodes) p = nodes[p].parent, ++steps;
    if (p >= 0) {
      os << "the node hierarchy has a cycle through node " << n;
      return os.str();
    }
  }
  for (const auto& inf : influences) {
    if (inf.node < 0 || inf.node >= num_nodes) return "influence refers to a missing node";
    if (!inf.inverse_bind.allFinite()) return "inverse bind matrix is not finite";
  }
  if (v == 0 || NumFaces() == 0) return "the rig has no triangles";
  if (!rest_vertices.allFinite()) return "rest vertices are not finite";
  if (faces.minCoeff() < 0 || faces.maxCoeff() >= v) return "face index out of range";
  if (vertex_influences.cols() != v || vertex_weights.cols() != v) {
    return "skin weights do not cover every vertex";
  }
  for (int i = 0; i < v; ++i) {
    double sum = 0;
    for (int k = 0; k < kMaxVertexInfluences; ++k) {
      const int inf = vertex_influences(k, i);
      const float w = vertex_weights(k, i);
      if (inf < -1 || inf >= static_cast<int>(influences.size())) {
        os << "vertex " << i << " refers to a missing influence " << inf;
        return os.str();
      }
      if (!std::isfinite(w) || w < 0 || (inf < 0 && w != 0)) {
        os << "vertex " << i << " has an invalid skin weight";
        return os.str();
      }
      sum += w;
    }
    if (std::abs(sum - 1) > 1e-3) {
      os << "skin weights of vertex " << i << " sum to " << sum << ", expected 1";
      return os.str();
    }
  }
  if (vertex_colors.cols() != v) return "vertex colours do not cover every vertex";
  if (uvs.cols() != 0 && uvs.cols() != v) return "UVs do not cover every vertex";
  if (static_cast<int>(face_material.size()) != NumFaces()) return "face materials missing";
  for (int m : face_material) {
    if (m < 0 || m >= static_cast<int>(materials.size())) return "face material out of range";
  }
  for (const auto& m : materials) {
    if (m.texture >= static_cast<int>(textures.size())) return "material texture out of range";
    if (m.texture >= 0 && uvs.cols() != v) return "a textured material needs UVs";
  }
  for (const auto& t : textures) {
    if (t.empty() || t.type() != CV_8UC3) return "textures must be non-empty RGB8 images";
  }
  for (const auto& g : morph_groups) {
    if (g.node < 0 || g.node >= num_nodes) return "morph group refers to a missing node";
    for (int i : g.vertices) {
      if (i < 0 || i >= v) return "morph group vertex out of range";
    }
    for (const auto& d : g.deltas) {
      if (d.cols() != static_cast<int>(g.vertices.size())) return "morph target size mismatch";
    }
  }
  for (const auto& anim : animations) {
    for (const auto& c : anim.channels) {
      if (c.node < 0 || c.node >= num_nodes) {
        return "animation '" + anim.name + "' drives a missing node";
      }
      const std::string problem = c.Validate();
      if (!problem.empty()) return "animation '" + anim.name + "': " + problem;
    }
  }
  return "";
}

namespace {

Eigen::Matrix4d ComposeTrs(const Eigen::Vector3d& t, const Eigen::Quaterniond& r,
                           const Eigen::Vector3d& s) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = r.normalized().toRotationMatrix() * s.asDiagonal();
  m.topRightCorner<3, 1>() = t;
  return m;
}

}  // namespace

std::vector<Eigen::Matrix4d> NodeGlobalTransforms(const Rig& rig, const Animation* animation,
                                                  double t,
                                                  std::vector<Eigen::VectorXd>* morph_weights) {
  const int n = static_cast<int>(rig.nodes.size());
  std::vector<Eigen::Vector3d> translation(n), scale(n);
  std::vector<Eigen::Quaterniond> rotation(n);
  std::vector<Eigen::VectorXd> weights(n);
  for (int i = 0; i < n; ++i) {
    translation[i] = rig.nodes[i].translation;
    rotation[i] = rig.nodes[i].rotation;
    scale[i] = rig.nodes[i].scale;
    weights[i] = rig.nodes[i].morph_weights;
  }
  if (animation != nullptr) {
    for (const auto& c : animation->channels) {
      const Eigen::VectorXd v = SampleChannel(c, t);
      switch (c.path) {
        case ChannelPath::kTranslation:
          translation[c.node] = v.head<3>();
          break;
        case ChannelPath::kScale:
          scale[c.node] = v.head<3>();
          break;
        case ChannelPath::kRotation:
          rotation[c.node] = Eigen::Quaterniond(v[3], v[0], v[1], v[2]);
          break;
        case ChannelPath::kWeights:
          weights[c.node] = v;
          break;
      }
    }
  }
  std::vector<Eigen::Matrix4d> global(n);
  std::vector<char> done(n, 0);  // 0: not yet, 1: in progress, 2: done
  std::function<void(int)> compute = [&](int i) {
    if (done[i] == 2) return;
    CHECK(done[i] == 0) << "the node hierarchy has a cycle through node " << i
                        << " (Rig::Validate refuses such rigs)";
    done[i] = 1;
    const Eigen::Matrix4d local = ComposeTrs(translation[i], rotation[i], scale[i]);
    const int p = rig.nodes[i].parent;
    if (p >= 0) {
      compute(p);
      global[i] = global[p] * local;
    } else {
      global[i] = local;
    }
    done[i] = 2;
  };
  for (int i = 0; i < n; ++i) compute(i);
  if (morph_weights != nullptr) *morph_weights = std::move(weights);
  return global;
}

Eigen::Matrix3Xd LinearBlendSkinning(const Rig& rig, const Eigen::Matrix3Xd& rest_vertices,
                                     const std::vector<Eigen::Matrix4d>& skin_matrices) {
  CHECK_EQ(skin_matrices.size(), rig.influences.size());
  const int v = static_cast<int>(rest_vertices.cols());
  Eigen::Matrix3Xd out(3, v);
  for (int i = 0; i < v; ++i) {
    Eigen::Matrix<double, 3, 4> m = Eigen::Matrix<double, 3, 4>::Zero();
    for (int k = 0; k < kMaxVertexInfluences; ++k) {
      const int inf = rig.vertex_influences(k, i);
      if (inf < 0) continue;
      const double w = rig.vertex_weights(k, i);
      if (w == 0) continue;
      m += w * skin_matrices[inf].topRows<3>();
    }
    out.col(i) = m.leftCols<3>() * rest_vertices.col(i) + m.col(3);
  }
  return out;
}

Eigen::Matrix3Xd PoseRig(const Rig& rig, const Animation* animation, double t) {
  std::vector<Eigen::VectorXd> morph_weights;
  const std::vector<Eigen::Matrix4d> global =
      NodeGlobalTransforms(rig, animation, t, &morph_weights);
  std::vector<Eigen::Matrix4d> skin(rig.influences.size());
  for (size_t i = 0; i < skin.size(); ++i) {
    skin[i] = global[rig.influences[i].node] * rig.influences[i].inverse_bind;
  }
  if (rig.morph_groups.empty()) return LinearBlendSkinning(rig, rig.rest_vertices, skin);
  Eigen::Matrix3Xd rest = rig.rest_vertices;
  for (const auto& g : rig.morph_groups) {
    const Eigen::VectorXd& w = morph_weights[g.node];
    const int targets = std::min<int>(static_cast<int>(g.deltas.size()), w.size());
    for (int k = 0; k < targets; ++k) {
      if (w[k] == 0) continue;
      for (size_t j = 0; j < g.vertices.size(); ++j) {
        rest.col(g.vertices[j]) += w[k] * g.deltas[k].col(j);
      }
    }
  }
  return LinearBlendSkinning(rig, rest, skin);
}

Eigen::Vector3f SampleTexture(const cv::Mat& texture, float u, float v) {
  const int w = texture.cols, h = texture.rows;
  // Texel centres sit at (i + 0.5) / w; repeat wrapping.
  const float x = u * w - 0.5f, y = v * h - 0.5f;
  const float fx = std::floor(x), fy = std::floor(y);
  const float ax = x - fx, ay = y - fy;
  auto wrap = [](int i, int n) {
    i %= n;
    return i < 0 ? i + n : i;
  };
  const int x0 = wrap(static_cast<int>(fx), w), x1 = wrap(static_cast<int>(fx) + 1, w);
  const int y0 = wrap(static_cast<int>(fy), h), y1 = wrap(static_cast<int>(fy) + 1, h);
  auto texel = [&](int xx, int yy) {
    const cv::Vec3b& p = texture.at<cv::Vec3b>(yy, xx);
    return Eigen::Vector3f(p[0], p[1], p[2]);
  };
  const Eigen::Vector3f c = (1 - ay) * ((1 - ax) * texel(x0, y0) + ax * texel(x1, y0)) +
                            ay * ((1 - ax) * texel(x0, y1) + ax * texel(x1, y1));
  return c / 255.0f;
}

Eigen::Matrix3Xf RigVertexColors(const Rig& rig) {
  const int v = rig.NumVertices();
  Eigen::Matrix3Xf colors = rig.vertex_colors;
  // A vertex shared by faces of several materials takes the first one's.
  std::vector<int> material(v, -1);
  for (int f = 0; f < rig.NumFaces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int& m = material[rig.faces(k, f)];
      if (m < 0) m = rig.face_material[f];
    }
  }
  for (int i = 0; i < v; ++i) {
    if (material[i] < 0) continue;
    const RigMaterial& mat = rig.materials[material[i]];
    Eigen::Vector3f c = colors.col(i).cwiseProduct(mat.base_color.head<3>().cast<float>());
    if (mat.texture >= 0) {
      c = c.cwiseProduct(SampleTexture(rig.textures[mat.texture], rig.uvs(0, i), rig.uvs(1, i)));
    }
    colors.col(i) = c;
  }
  return colors;
}

Eigen::Matrix3Xd VertexNormals(const Eigen::Matrix3Xd& vertices, const Eigen::Matrix3Xi& faces) {
  Eigen::Matrix3Xd normals = Eigen::Matrix3Xd::Zero(3, vertices.cols());
  for (int f = 0; f < faces.cols(); ++f) {
    const Eigen::Vector3d a = vertices.col(faces(0, f)), b = vertices.col(faces(1, f)),
                          c = vertices.col(faces(2, f));
    const Eigen::Vector3d n = (b - a).cross(c - a);  // length = 2 x area
    for (int k = 0; k < 3; ++k) normals.col(faces(k, f)) += n;
  }
  for (int i = 0; i < normals.cols(); ++i) {
    const double len = normals.col(i).norm();
    if (len > 0) normals.col(i) /= len;
  }
  return normals;
}

}  // namespace banmo::synth
