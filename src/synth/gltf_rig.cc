#include "banmo/synth/gltf_rig.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <utility>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "gltf_accessors.h"
#include "gltf_document.h"
#include "gltf_draco.h"

namespace banmo::synth {
namespace {

using internal::GltfAccessors;

Eigen::Matrix4d NodeLocalMatrix(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) {
    Eigen::Matrix4d m;
    for (int i = 0; i < 16; ++i) m(i % 4, i / 4) = n.matrix[i];  // column-major
    return m;
  }
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  Eigen::Quaterniond r = Eigen::Quaterniond::Identity();
  if (n.rotation.size() == 4)
    r = Eigen::Quaterniond(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
  Eigen::Vector3d s = Eigen::Vector3d::Ones(), t = Eigen::Vector3d::Zero();
  if (n.scale.size() == 3) s = Eigen::Vector3d(n.scale[0], n.scale[1], n.scale[2]);
  if (n.translation.size() == 3)
    t = Eigen::Vector3d(n.translation[0], n.translation[1], n.translation[2]);
  m.topLeftCorner<3, 3>() = r.normalized().toRotationMatrix() * s.asDiagonal();
  m.topRightCorner<3, 1>() = t;
  return m;
}

// Splits an affine matrix into T, R, S (for matrix-given nodes, which glTF
// forbids from being animated, so a polar decomposition is exact enough).
void DecomposeTrs(const Eigen::Matrix4d& m, RigNode* node) {
  node->translation = m.topRightCorner<3, 1>();
  Eigen::Matrix3d a = m.topLeftCorner<3, 3>();
  Eigen::Vector3d s(a.col(0).norm(), a.col(1).norm(), a.col(2).norm());
  if (a.determinant() < 0) s[0] = -s[0];
  for (int i = 0; i < 3; ++i) {
    if (s[i] != 0) a.col(i) /= s[i];
  }
  node->scale = s;
  node->rotation = Eigen::Quaterniond(a).normalized();
}

cv::Mat ImageToRgb8(const GltfAccessors& reader, const tinygltf::Image& image, int index) {
  if (image.image.empty() || image.width <= 0 || image.height <= 0) {
    reader.Fail("image ", index, " ('", image.name, "') could not be decoded");
  }
  const int comps = image.component;
  if (comps < 1 || comps > 4) reader.Fail("image ", index, " has ", comps, " components");
  cv::Mat out(image.height, image.width, CV_8UC3);
  const bool sixteen = image.bits == 16;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const size_t base = (static_cast<size_t>(y) * image.width + x) * comps;
      auto channel = [&](int c) -> unsigned char {
        if (sixteen) {
          uint16_t v;
          std::memcpy(&v, image.image.data() + 2 * (base + c), 2);
          return static_cast<unsigned char>(v >> 8);
        }
        return image.image[base + c];
      };
      cv::Vec3b& p = out.at<cv::Vec3b>(y, x);
      if (comps < 3) {
        p = cv::Vec3b(channel(0), channel(0), channel(0));
      } else {
        p = cv::Vec3b(channel(0), channel(1), channel(2));
      }
    }
  }
  return out;
}

// Which TEXCOORD_n feeds a material's base colour texture, and its
// KHR_texture_transform (uv' = T R S uv, in homogeneous coordinates).
struct MaterialUv {
  int texcoord = 0;
  Eigen::Matrix3d transform = Eigen::Matrix3d::Identity();
};

MaterialUv ReadMaterialUv(const tinygltf::TextureInfo& info) {
  MaterialUv out;
  out.texcoord = info.texCoord;
  const auto it = info.extensions.find(internal::kTextureTransformExtension);
  if (it == info.extensions.end() || !it->second.IsObject()) return out;
  const tinygltf::Value& t = it->second;
  auto number = [](const tinygltf::Value& v, double fallback) {
    return v.IsNumber() ? v.GetNumberAsDouble() : fallback;
  };
  Eigen::Vector2d offset(0, 0), scale(1, 1);
  if (t.Get("offset").IsArray() && t.Get("offset").ArrayLen() == 2) {
    offset = Eigen::Vector2d(number(t.Get("offset").Get(0), 0), number(t.Get("offset").Get(1), 0));
  }
  if (t.Get("scale").IsArray() && t.Get("scale").ArrayLen() == 2) {
    scale = Eigen::Vector2d(number(t.Get("scale").Get(0), 1), number(t.Get("scale").Get(1), 1));
  }
  const double rotation = number(t.Get("rotation"), 0);
  if (t.Get("texCoord").IsNumber()) out.texcoord = t.Get("texCoord").GetNumberAsInt();
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity(), R = Eigen::Matrix3d::Identity(),
                  S = Eigen::Matrix3d::Identity();
  T(0, 2) = offset[0];
  T(1, 2) = offset[1];
  // The extension's rotation matrix (counter-clockwise in UV space).
  R << std::cos(rotation), std::sin(rotation), 0, -std::sin(rotation), std::cos(rotation), 0, 0, 0,
      1;
  S(0, 0) = scale[0];
  S(1, 1) = scale[1];
  out.transform = T * R * S;
  return out;
}

// Builds a Rig from a parsed glTF document, one part at a time.
class GltfRigBuilder {
 public:
  GltfRigBuilder(const std::string& path, const tinygltf::Model& model)
      : path_(path), model_(model), reader_(path, model) {}

  Rig Build() {
    rig_.name = std::filesystem::path(path_).stem().string();
    ReadNodes();
    rest_global_ = NodeGlobalTransforms(rig_, nullptr, 0);
    ReadMaterials();
    for (int node_index : SceneOrder()) AddMeshNode(node_index);
    if (faces_.empty()) reader_.Fail("no triangles in the default scene");
    StoreMesh();
    ReadAnimations();
    const std::string problem = rig_.Validate();
    if (!problem.empty()) reader_.Fail(problem);
    return std::move(rig_);
  }

 private:
  int NumNodes() const { return static_cast<int>(model_.nodes.size()); }

  void ReadNodes() {
    rig_.nodes.resize(NumNodes());
    for (int i = 0; i < NumNodes(); ++i) {
      const tinygltf::Node& n = model_.nodes[i];
      RigNode& node = rig_.nodes[i];
      node.name = n.name.empty() ? "node" + std::to_string(i) : n.name;
      if (n.matrix.size() == 16) {
        DecomposeTrs(NodeLocalMatrix(n), &node);
      } else {
        const Eigen::Matrix4d m = NodeLocalMatrix(n);
        node.translation = m.topRightCorner<3, 1>();
        if (n.rotation.size() == 4) {
          node.rotation =
              Eigen::Quaterniond(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2])
                  .normalized();
        }
        if (n.scale.size() == 3) node.scale = Eigen::Vector3d(n.scale[0], n.scale[1], n.scale[2]);
      }
      for (int c : n.children) {
        if (c < 0 || c >= NumNodes()) reader_.Fail("node ", i, " has a missing child ", c);
        if (c == i) {
          reader_.Fail("node ", i, " ('", node.name,
                       "') lists itself as a child: the node graph has a cycle");
        }
        if (rig_.nodes[c].parent >= 0) reader_.Fail("node ", c, " has two parents");
        rig_.nodes[c].parent = i;
      }
    }
    CheckNodeTree();
    for (int i = 0; i < NumNodes(); ++i) {
      const tinygltf::Node& n = model_.nodes[i];
      if (n.mesh < 0) continue;
      if (n.mesh >= static_cast<int>(model_.meshes.size())) {
        reader_.Fail("node ", i, ": bad mesh index");
      }
      const tinygltf::Mesh& mesh = model_.meshes[n.mesh];
      const std::vector<double>& w = !n.weights.empty() ? n.weights : mesh.weights;
      if (!w.empty())
        rig_.nodes[i].morph_weights = Eigen::Map<const Eigen::VectorXd>(w.data(), w.size());
    }
  }

  // Textures and materials (a default white material last).
  void ReadMaterials() {
    for (size_t i = 0; i < model_.images.size(); ++i) {
      rig_.textures.push_back(ImageToRgb8(reader_, model_.images[i], static_cast<int>(i)));
    }
    for (const auto& mat : model_.materials) {
      RigMaterial m;
      const auto& pbr = mat.pbrMetallicRoughness;
      if (pbr.baseColorFactor.size() == 4) {
        m.base_color = Eigen::Vector4d(pbr.baseColorFactor[0], pbr.baseColorFactor[1],
                                       pbr.baseColorFactor[2], pbr.baseColorFactor[3]);
      }
      if (pbr.baseColorTexture.index >= 0) {
        if (pbr.baseColorTexture.index >= static_cast<int>(model_.textures.size())) {
          reader_.Fail("material '", mat.name, "': texture index out of range");
        }
        const int source = model_.textures[pbr.baseColorTexture.index].source;
        if (source < 0 || source >= static_cast<int>(rig_.textures.size())) {
          reader_.Fail("material '", mat.name, "': texture without a valid image");
        }
        m.texture = source;
      }
      rig_.materials.push_back(m);
      material_uv_.push_back(ReadMaterialUv(pbr.baseColorTexture));
    }
    default_material_ = static_cast<int>(rig_.materials.size());
    rig_.materials.push_back(RigMaterial{});
    material_uv_.push_back(MaterialUv{});
  }

  // Scene traversal order: nodes of the default scene (or all roots).
  // Refuses a node graph with a cycle (a node that is its own ancestor),
  // before anything walks the hierarchy.
  void CheckNodeTree() const {
    for (int i = 0; i < NumNodes(); ++i) {
      int p = rig_.nodes[i].parent;
      for (int steps = 0; p >= 0 && steps <= NumNodes(); ++steps) p = rig_.nodes[p].parent;
      if (p >= 0) {
        reader_.Fail("the node graph has a cycle: node ", i, " ('", rig_.nodes[i].name,
                     "') is its own ancestor (glTF nodes must form trees)");
      }
    }
  }

  std::vector<int> SceneOrder() const {
    std::vector<int> roots;
    const int scene = model_.defaultScene >= 0 ? model_.defaultScene : 0;
    if (scene < static_cast<int>(model_.scenes.size())) {
      roots = model_.scenes[scene].nodes;
    } else {
      for (int i = 0; i < NumNodes(); ++i) {
        if (rig_.nodes[i].parent < 0) roots.push_back(i);
      }
    }
    std::vector<int> order;
    std::function<void(int)> visit = [&](int i) {
      if (i < 0 || i >= NumNodes()) reader_.Fail("scene refers to a missing node ", i);
      order.push_back(i);
      for (int c : model_.nodes[i].children) visit(c);
    };
    for (int r : roots) visit(r);
    return order;
  }

  // The rig influences of skin `s` (one per joint), created on first use.
  // Each skin has its own influences, so files with one skin per mesh (as
  // three.js writes them) keep each mesh's inverse bind matrices.
  const std::vector<int>& SkinInfluences(int s) {
    auto it = skin_influences_.find(s);
    if (it != skin_influences_.end()) return it->second;
    if (s < 0 || s >= static_cast<int>(model_.skins.size())) reader_.Fail("bad skin index ", s);
    const tinygltf::Skin& skin = model_.skins[s];
    Eigen::MatrixXd ibm;
    if (skin.inverseBindMatrices >= 0) {
      ibm = reader_.ReadFloats(skin.inverseBindMatrices, "skin inverseBindMatrices");
      if (ibm.rows() != 16 || ibm.cols() != static_cast<int>(skin.joints.size())) {
        reader_.Fail("skin ", s, ": expected one MAT4 inverse bind matrix per joint");
      }
    }
    std::vector<RigInfluence> infs;
    for (size_t j = 0; j < skin.joints.size(); ++j) {
      RigInfluence inf;
      inf.node = skin.joints[j];
      if (inf.node < 0 || inf.node >= NumNodes()) reader_.Fail("skin ", s, ": missing joint node");
      if (ibm.size() > 0) {
        for (int k = 0; k < 16; ++k) inf.inverse_bind(k % 4, k / 4) = ibm(k, j);
      }
      infs.push_back(inf);
    }
    const Eigen::Matrix4d offset = SkinBindOffset(infs);
    skin_offset_[s] = offset;
    const Eigen::Matrix4d offset_inverse = offset.inverse();
    std::vector<int> ids;
    for (RigInfluence& inf : infs) {
      inf.inverse_bind = inf.inverse_bind * offset_inverse;
      ids.push_back(static_cast<int>(rig_.influences.size()));
      rig_.influences.push_back(inf);
    }
    return skin_influences_[s] = ids;
  }

  // The matrix M that the joints of a skin apply to its mesh at the rest
  // pose (rest_global[joint] * inverse_bind, the same for most joints), or
  // the identity. Exporters such as FBX2glTF write skins with M = the mesh
  // node's transform (a 90 degree turn and a 100x scale): the mesh at rest is
  // then about M * POSITION, not POSITION. The loader stores rest vertices
  // M * POSITION and inverse binds IBM * M^-1: every posed frame is exactly
  // as before (M cancels), while the rest vertices, which the scene is
  // normalised by, match the rest pose. M is the medoid of the joints'
  // matrices; it is used only if at least half of the joints agree with it
  // within 5 % (node rest poses differ from the bind pose by a few degrees
  // in such files) and it is not within 5 % of the identity already.
  Eigen::Matrix4d SkinBindOffset(const std::vector<RigInfluence>& infs) const {
    const Eigen::Matrix4d identity = Eigen::Matrix4d::Identity();
    const int n = static_cast<int>(infs.size());
    if (n == 0) return identity;
    std::vector<Eigen::Matrix4d> m(n);
    for (int j = 0; j < n; ++j) m[j] = rest_global_[infs[j].node] * infs[j].inverse_bind;
    int best = -1;
    double best_sum = std::numeric_limits<double>::infinity();
    for (int j = 0; j < n; ++j) {
      if (!m[j].allFinite()) continue;
      double sum = 0;
      for (int k = 0; k < n; ++k) sum += m[k].allFinite() ? (m[k] - m[j]).norm() : 0.0;
      if (sum < best_sum) best = j, best_sum = sum;
    }
    if (best < 0) return identity;
    const Eigen::Matrix4d& medoid = m[best];
    const double tolerance = 0.05 * medoid.topLeftCorner<3, 3>().norm();
    int agree = 0;
    for (int j = 0; j < n; ++j) agree += (m[j] - medoid).norm() <= tolerance ? 1 : 0;
    const bool affine = (medoid.row(3) - identity.row(3)).norm() <= 1e-6;
    const double det = medoid.topLeftCorner<3, 3>().determinant();
    if (2 * agree < n || !affine || !(std::abs(det) > 1e-12) ||
        (medoid - identity).norm() <= 0.05 * std::sqrt(3.0)) {
      return identity;
    }
    return medoid;
  }

  void AddMeshNode(int node_index) {
    const tinygltf::Node& n = model_.nodes[node_index];
    if (n.mesh < 0) return;
    const tinygltf::Mesh& mesh = model_.meshes[n.mesh];
    int rigid_influence = -1;
    if (n.skin < 0) {
      RigInfluence inf;
      inf.node = node_index;
      inf.inverse_bind = rest_global_[node_index].inverse();
      rigid_influence = static_cast<int>(rig_.influences.size());
      rig_.influences.push_back(inf);
    }
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        LOG(WARNING) << path_ << ": mesh '" << mesh.name << "' primitive " << pi
                     << " is not made of triangles; skipped";
        continue;
      }
      std::vector<int> draco_indices;
      const bool draco =
          internal::DecodeDracoPrimitive(model_, prim, mesh.name, &reader_, &draco_indices);
      const int material = prim.material >= 0 ? prim.material : default_material_;
      if (material >= static_cast<int>(rig_.materials.size())) reader_.Fail("bad material index");
      const int base = static_cast<int>(positions_.size());
      const int count = AddVertices(node_index, mesh, prim, material);
      AddSkinWeights(n.skin, rigid_influence, mesh, prim, base, count);
      AddMorphTargets(node_index, prim, base, count);
      AddFaces(mesh, prim, mode, material, base, count, draco ? &draco_indices : nullptr);
    }
  }

  static int Attribute(const tinygltf::Primitive& prim, const std::string& name) {
    const auto it = prim.attributes.find(name);
    return it == prim.attributes.end() ? -1 : it->second;
  }

  // The transform from a mesh node's POSITIONs to the rest pose: its global
  // transform if unskinned, its skin's SkinBindOffset if skinned.
  Eigen::Matrix4d ToRest(int node_index) {
    const int skin = model_.nodes[node_index].skin;
    if (skin < 0) return rest_global_[node_index];
    SkinInfluences(skin);
    return skin_offset_.at(skin);
  }

  // Positions, colours and UVs; returns the number of vertices added.
  int AddVertices(int node_index, const tinygltf::Mesh& mesh, const tinygltf::Primitive& prim,
                  int material) {
    const int position = Attribute(prim, "POSITION");
    if (position < 0) reader_.Fail("mesh '", mesh.name, "': primitive without POSITION");
    const Eigen::MatrixXd pos = reader_.ReadFloats(position, "POSITION");
    if (pos.rows() != 3) reader_.Fail("POSITION must be VEC3");
    const int count = static_cast<int>(pos.cols());
    const Eigen::Matrix4d to_rest = ToRest(node_index);
    for (int i = 0; i < count; ++i) {
      positions_.push_back((to_rest * pos.col(i).homogeneous()).head<3>());
    }
    const int color = Attribute(prim, "COLOR_0");
    if (color >= 0) {
      const Eigen::MatrixXd col = reader_.ReadFloats(color, "COLOR_0");
      if (col.cols() != count || col.rows() < 3) reader_.Fail("COLOR_0 size mismatch");
      for (int i = 0; i < count; ++i) {
        Eigen::Vector3f c;
        for (int k = 0; k < 3; ++k) {
          c[k] = static_cast<float>(std::pow(std::clamp(col(k, i), 0.0, 1.0), 1 / 2.2));
        }
        colors_.push_back(c);
      }
    } else {
      for (int i = 0; i < count; ++i) colors_.emplace_back(1, 1, 1);
    }
    // UVs of the material's base colour texture.
    const MaterialUv& muv = material_uv_[material];
    const std::string uv_name = "TEXCOORD_" + std::to_string(muv.texcoord);
    const int texcoord = Attribute(prim, uv_name);
    if (texcoord >= 0) {
      const Eigen::MatrixXd uv = reader_.ReadFloats(texcoord, uv_name.c_str());
      if (uv.cols() != count || uv.rows() != 2) reader_.Fail(uv_name, " size mismatch");
      for (int i = 0; i < count; ++i) {
        uvs_.push_back((muv.transform * uv.col(i).homogeneous()).head<2>().cast<float>());
      }
      any_uv_ = true;
    } else {
      if (rig_.materials[material].texture >= 0) {
        reader_.Fail("mesh '", mesh.name, "': textured material but no ", uv_name);
      }
      for (int i = 0; i < count; ++i) uvs_.emplace_back(0, 0);
    }
    return count;
  }

  void AddSkinWeights(int skin, int rigid_influence, const tinygltf::Mesh& mesh,
                      const tinygltf::Primitive& prim, int base, int count) {
    for (int i = 0; i < count; ++i) {
      std::array<int, kMaxVertexInfluences> ids;
      std::array<float, kMaxVertexInfluences> ws;
      ids.fill(-1);
      ws.fill(0);
      if (skin < 0) {
        ids[0] = rigid_influence;
        ws[0] = 1;
      }
      vinf_.push_back(ids);
      vw_.push_back(ws);
    }
    if (skin < 0) return;
    const std::vector<int>& skin_ids = SkinInfluences(skin);
    std::vector<Eigen::MatrixXi> joints;
    std::vector<Eigen::MatrixXd> weights;
    for (int set = 0; set < 2; ++set) {
      const int j = Attribute(prim, "JOINTS_" + std::to_string(set));
      const int w = Attribute(prim, "WEIGHTS_" + std::to_string(set));
      if (j < 0 || w < 0) break;
      joints.push_back(reader_.ReadInts(j, "JOINTS"));
      weights.push_back(reader_.ReadFloats(w, "WEIGHTS"));
      if (joints.back().rows() != 4 || weights.back().rows() != 4 ||
          joints.back().cols() != count || weights.back().cols() != count) {
        reader_.Fail("mesh '", mesh.name, "': JOINTS/WEIGHTS must be VEC4 per vertex");
      }
    }
    if (joints.empty()) {
      reader_.Fail("mesh '", mesh.name, "': skinned node without JOINTS_0/WEIGHTS_0");
    }
    std::vector<std::pair<int, double>> pairs;
    for (int i = 0; i < count; ++i) {
      pairs.clear();
      for (size_t set = 0; set < joints.size(); ++set) {
        for (int k = 0; k < 4; ++k) {
          const double w = weights[set](k, i);
          if (w <= 0) continue;
          const int jj = joints[set](k, i);
          if (jj < 0 || jj >= static_cast<int>(skin_ids.size())) {
            reader_.Fail("mesh '", mesh.name, "': joint index ", jj, " out of range");
          }
          pairs.emplace_back(skin_ids[jj], w);
        }
      }
      double sum = 0;
      for (const auto& p : pairs) sum += p.second;
      if (!(sum > 0)) reader_.Fail("mesh '", mesh.name, "': vertex ", i, " has no skin weight");
      for (size_t k = 0; k < pairs.size(); ++k) {
        vinf_[base + i][k] = pairs[k].first;
        vw_[base + i][k] = static_cast<float>(pairs[k].second / sum);
      }
    }
  }

  void AddMorphTargets(int node_index, const tinygltf::Primitive& prim, int base, int count) {
    if (prim.targets.empty()) return;
    const Eigen::Matrix4d to_rest = ToRest(node_index);
    RigMorphGroup group;
    group.node = node_index;
    for (int i = 0; i < count; ++i) group.vertices.push_back(base + i);
    for (const auto& target : prim.targets) {
      auto it = target.find("POSITION");
      Eigen::Matrix3Xd delta = Eigen::Matrix3Xd::Zero(3, count);
      if (it != target.end()) {
        const Eigen::MatrixXd d = reader_.ReadFloats(it->second, "morph target POSITION");
        if (d.rows() != 3 || d.cols() != count) reader_.Fail("morph target size mismatch");
        delta = to_rest.topLeftCorner<3, 3>() * d;
      }
      group.deltas.push_back(delta);
    }
    if (rig_.nodes[node_index].morph_weights.size() == 0) {
      rig_.nodes[node_index].morph_weights = Eigen::VectorXd::Zero(prim.targets.size());
    }
    rig_.morph_groups.push_back(std::move(group));
  }

  // Faces from the indices accessor, or `decoded` (a Draco primitive's
  // corners), or the vertices in order.
  void AddFaces(const tinygltf::Mesh& mesh, const tinygltf::Primitive& prim, int mode, int material,
                int base, int count, const std::vector<int>* decoded) {
    std::vector<int> idx;
    if (decoded != nullptr) {
      idx = *decoded;
    } else if (prim.indices >= 0) {
      const Eigen::MatrixXi ind = reader_.ReadInts(prim.indices, "indices");
      idx.assign(ind.data(), ind.data() + ind.size());
    } else {
      for (int i = 0; i < count; ++i) idx.push_back(i);
    }
    for (int i : idx) {
      if (i < 0 || i >= count) reader_.Fail("mesh '", mesh.name, "': index ", i, " out of range");
    }
    auto add_face = [&](int a, int b, int c) {
      if (a == b || b == c || a == c) return;
      faces_.emplace_back(base + a, base + b, base + c);
      face_material_.push_back(material);
    };
    const int ni = static_cast<int>(idx.size());
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      for (int i = 0; i + 2 < ni; i += 3) add_face(idx[i], idx[i + 1], idx[i + 2]);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (int i = 0; i + 2 < ni; ++i) {
        if (i % 2 == 0)
          add_face(idx[i], idx[i + 1], idx[i + 2]);
        else
          add_face(idx[i + 1], idx[i], idx[i + 2]);
      }
    } else {
      for (int i = 1; i + 1 < ni; ++i) add_face(idx[0], idx[i], idx[i + 1]);
    }
  }

  void StoreMesh() {
    const int v = static_cast<int>(positions_.size());
    rig_.rest_vertices.resize(3, v);
    rig_.vertex_colors.resize(3, v);
    rig_.vertex_influences.resize(kMaxVertexInfluences, v);
    rig_.vertex_weights.resize(kMaxVertexInfluences, v);
    if (any_uv_) rig_.uvs.resize(2, v);
    for (int i = 0; i < v; ++i) {
      rig_.rest_vertices.col(i) = positions_[i];
      rig_.vertex_colors.col(i) = colors_[i];
      if (any_uv_) rig_.uvs.col(i) = uvs_[i];
      for (int k = 0; k < kMaxVertexInfluences; ++k) {
        rig_.vertex_influences(k, i) = vinf_[i][k];
        rig_.vertex_weights(k, i) = vw_[i][k];
      }
    }
    rig_.faces.resize(3, faces_.size());
    for (size_t f = 0; f < faces_.size(); ++f) rig_.faces.col(f) = faces_[f];
    rig_.face_material = face_material_;
  }

  void ReadAnimations() {
    for (size_t ai = 0; ai < model_.animations.size(); ++ai) {
      const tinygltf::Animation& a = model_.animations[ai];
      Animation anim;
      anim.name = a.name.empty() ? "animation" + std::to_string(ai) : a.name;
      for (const auto& ch : a.channels) {
        if (ch.sampler < 0 || ch.sampler >= static_cast<int>(a.samplers.size())) {
          reader_.Fail("animation '", anim.name, "': channel with a missing sampler");
        }
        if (ch.target_node < 0 || ch.target_node >= NumNodes()) continue;  // no target (spec)
        anim.channels.push_back(ReadChannel(anim.name, ch, a.samplers[ch.sampler]));
      }
      rig_.animations.push_back(std::move(anim));
    }
  }

  AnimationChannel ReadChannel(const std::string& name, const tinygltf::AnimationChannel& ch,
                               const tinygltf::AnimationSampler& s) const {
    AnimationChannel c;
    c.node = ch.target_node;
    if (ch.target_path == "translation")
      c.path = ChannelPath::kTranslation;
    else if (ch.target_path == "rotation")
      c.path = ChannelPath::kRotation;
    else if (ch.target_path == "scale")
      c.path = ChannelPath::kScale;
    else if (ch.target_path == "weights")
      c.path = ChannelPath::kWeights;
    else
      reader_.Fail("animation '", name, "': unknown target path '", ch.target_path, "'");
    if (s.interpolation == "LINEAR" || s.interpolation.empty())
      c.interpolation = Interpolation::kLinear;
    else if (s.interpolation == "STEP")
      c.interpolation = Interpolation::kStep;
    else if (s.interpolation == "CUBICSPLINE")
      c.interpolation = Interpolation::kCubicSpline;
    else
      reader_.Fail("animation '", name, "': unknown interpolation '", s.interpolation, "'");
    const Eigen::MatrixXd in = reader_.ReadFloats(s.input, "animation input");
    if (in.rows() != 1) reader_.Fail("animation '", name, "': input must be SCALAR");
    c.times.assign(in.data(), in.data() + in.size());
    Eigen::MatrixXd out = reader_.ReadFloats(s.output, "animation output");
    if (c.path == ChannelPath::kWeights) {
      // Outputs are scalars: reshape to one column of morph weights per element.
      const int per_key = c.interpolation == Interpolation::kCubicSpline ? 3 : 1;
      const int elements = per_key * c.NumKeys();
      if (elements == 0 || out.size() % elements != 0) {
        reader_.Fail("animation '", name, "': weights output size mismatch");
      }
      const Eigen::MatrixXd flat = out;
      out = Eigen::Map<const Eigen::MatrixXd>(flat.data(), out.size() / elements, elements);
    }
    c.values = out;
    const std::string problem = c.Validate();
    if (!problem.empty()) reader_.Fail("animation '", name, "': ", problem);
    return c;
  }

  const std::string path_;
  const tinygltf::Model& model_;
  GltfAccessors reader_;
  Rig rig_;
  std::vector<Eigen::Matrix4d> rest_global_;
  std::vector<MaterialUv> material_uv_;
  int default_material_ = 0;
  std::map<int, std::vector<int>> skin_influences_;  // skin -> influence per joint
  std::map<int, Eigen::Matrix4d> skin_offset_;       // skin -> SkinBindOffset
  // The mesh of all primitives, in scene order.
  std::vector<Eigen::Vector3d> positions_;
  std::vector<Eigen::Vector3f> colors_;
  std::vector<Eigen::Vector2f> uvs_;
  std::vector<std::array<int, kMaxVertexInfluences>> vinf_;
  std::vector<std::array<float, kMaxVertexInfluences>> vw_;
  std::vector<Eigen::Vector3i> faces_;
  std::vector<int> face_material_;
  bool any_uv_ = false;
};

}  // namespace

Rig LoadGltfRig(const std::string& path) {
  const tinygltf::Model model = internal::ReadGltfDocument(path);
  return GltfRigBuilder(path, model).Build();
}

}  // namespace banmo::synth
