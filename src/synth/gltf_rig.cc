#include "banmo/synth/gltf_rig.h"

// Debian's libtinygltf-dev ships tinygltf as a shared library (with stb_image
// and JSON parsing compiled in), so TINYGLTF_IMPLEMENTATION is not defined
// here: see /usr/share/doc/libtinygltf-dev/README.Debian.
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <utility>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo::synth {
namespace {

class GltfReader {
 public:
  GltfReader(const std::string& path, const tinygltf::Model& model) : path_(path), m_(model) {}

  // Accessor `index` as a (components x count) matrix of doubles, with
  // normalised integer types mapped to [0, 1] / [-1, 1] as the spec says.
  Eigen::MatrixXd ReadFloats(int index, const char* what) const {
    const tinygltf::Accessor& a = Accessor(index, what);
    const int comps = tinygltf::GetNumComponentsInType(a.type);
    if (comps <= 0) Fail(what, ": accessor ", index, " has an unsupported type");
    Eigen::MatrixXd out(comps, a.count);
    ForEachComponent(a, what, [&](size_t i, int c, double value) { out(c, i) = value; });
    if (!out.allFinite()) Fail(what, ": accessor ", index, " has NaN/Inf values");
    return out;
  }

  // Integer accessor (indices, joints) as a (components x count) matrix.
  Eigen::MatrixXi ReadInts(int index, const char* what) const {
    const tinygltf::Accessor& a = Accessor(index, what);
    if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
      Fail(what, ": accessor ", index, " must have an integer component type");
    }
    const int comps = tinygltf::GetNumComponentsInType(a.type);
    Eigen::MatrixXi out(comps, a.count);
    tinygltf::Accessor raw = a;
    raw.normalized = false;
    ForEachComponent(raw, what,
                     [&](size_t i, int c, double value) { out(c, i) = static_cast<int>(value); });
    return out;
  }

  template <typename... Args>
  [[noreturn]] void Fail(Args&&... args) const {
    ThrowInputError(path_, ": ", std::forward<Args>(args)...);
  }

 private:
  const tinygltf::Accessor& Accessor(int index, const char* what) const {
    if (index < 0 || index >= static_cast<int>(m_.accessors.size())) {
      Fail(what, ": accessor index ", index, " out of range");
    }
    const tinygltf::Accessor& a = m_.accessors[index];
    if (a.sparse.isSparse) Fail(what, ": sparse accessors are not supported");
    return a;
  }

  void ForEachComponent(const tinygltf::Accessor& a, const char* what,
                        const std::function<void(size_t, int, double)>& fn) const {
    const int comps = tinygltf::GetNumComponentsInType(a.type);
    const int csize = tinygltf::GetComponentSizeInBytes(a.componentType);
    if (comps <= 0 || csize <= 0) Fail(what, ": unsupported accessor type");
    if (a.count == 0) return;
    if (a.bufferView < 0 || a.bufferView >= static_cast<int>(m_.bufferViews.size())) {
      Fail(what, ": accessor without a valid bufferView");
    }
    const tinygltf::BufferView& view = m_.bufferViews[a.bufferView];
    if (view.buffer < 0 || view.buffer >= static_cast<int>(m_.buffers.size())) {
      Fail(what, ": bufferView without a valid buffer");
    }
    const std::vector<unsigned char>& data = m_.buffers[view.buffer].data;
    const size_t elem = static_cast<size_t>(comps) * csize;
    const size_t stride = view.byteStride > 0 ? view.byteStride : elem;
    const size_t begin = view.byteOffset + a.byteOffset;
    const size_t last_end = begin + stride * (a.count - 1) + elem;
    if (last_end > view.byteOffset + view.byteLength || last_end > data.size()) {
      Fail(what, ": accessor reads past the end of its buffer");
    }
    for (size_t i = 0; i < a.count; ++i) {
      const unsigned char* p = data.data() + begin + stride * i;
      for (int c = 0; c < comps; ++c) {
        const unsigned char* q = p + c * csize;
        double v = 0;
        switch (a.componentType) {
          case TINYGLTF_COMPONENT_TYPE_FLOAT: {
            float f;
            std::memcpy(&f, q, 4);
            v = f;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
            v = a.normalized ? *q / 255.0 : *q;
            break;
          case TINYGLTF_COMPONENT_TYPE_BYTE: {
            const auto s = static_cast<signed char>(*q);
            v = a.normalized ? std::max(s / 127.0, -1.0) : s;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            uint16_t s;
            std::memcpy(&s, q, 2);
            v = a.normalized ? s / 65535.0 : s;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_SHORT: {
            int16_t s;
            std::memcpy(&s, q, 2);
            v = a.normalized ? std::max(s / 32767.0, -1.0) : s;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
            uint32_t s;
            std::memcpy(&s, q, 4);
            v = s;
            break;
          }
          default:
            Fail(what, ": unsupported component type ", a.componentType);
        }
        fn(i, c, v);
      }
    }
  }

  std::string path_;
  const tinygltf::Model& m_;
};

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

cv::Mat ImageToRgb8(const GltfReader& reader, const tinygltf::Image& image, int index) {
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

}  // namespace

Rig LoadGltfRig(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) ThrowInputError(path, ": no such glTF file");
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  bool ok = false;
  if (ext == ".glb") {
    ok = loader.LoadBinaryFromFile(&model, &err, &warn, path);
  } else if (ext == ".gltf") {
    ok = loader.LoadASCIIFromFile(&model, &err, &warn, path);
  } else {
    ThrowInputError(path, ": expected a .glb or .gltf file");
  }
  if (!ok) ThrowInputError(path, ": cannot read glTF: ", err.empty() ? "unknown error" : err);
  if (!warn.empty()) LOG(WARNING) << path << ": " << warn;
  const GltfReader reader(path, model);

  Rig rig;
  rig.name = std::filesystem::path(path).stem().string();
  const int num_nodes = static_cast<int>(model.nodes.size());
  rig.nodes.resize(num_nodes);
  for (int i = 0; i < num_nodes; ++i) {
    const tinygltf::Node& n = model.nodes[i];
    RigNode& node = rig.nodes[i];
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
      if (c < 0 || c >= num_nodes) reader.Fail("node ", i, " has a missing child ", c);
      if (rig.nodes[c].parent >= 0) reader.Fail("node ", c, " has two parents");
      rig.nodes[c].parent = i;
    }
  }
  for (int i = 0; i < num_nodes; ++i) {
    const tinygltf::Node& n = model.nodes[i];
    if (n.mesh < 0) continue;
    if (n.mesh >= static_cast<int>(model.meshes.size()))
      reader.Fail("node ", i, ": bad mesh index");
    const tinygltf::Mesh& mesh = model.meshes[n.mesh];
    if (!n.weights.empty()) {
      rig.nodes[i].morph_weights =
          Eigen::Map<const Eigen::VectorXd>(n.weights.data(), n.weights.size());
    } else if (!mesh.weights.empty()) {
      rig.nodes[i].morph_weights =
          Eigen::Map<const Eigen::VectorXd>(mesh.weights.data(), mesh.weights.size());
    }
  }
  const std::vector<Eigen::Matrix4d> rest_global = NodeGlobalTransforms(rig, nullptr, 0);

  // Textures and materials (a default white material last).
  for (size_t i = 0; i < model.images.size(); ++i) {
    rig.textures.push_back(ImageToRgb8(reader, model.images[i], static_cast<int>(i)));
  }
  std::vector<int> material_texcoord;
  for (const auto& mat : model.materials) {
    RigMaterial m;
    const auto& pbr = mat.pbrMetallicRoughness;
    if (pbr.baseColorFactor.size() == 4) {
      m.base_color = Eigen::Vector4d(pbr.baseColorFactor[0], pbr.baseColorFactor[1],
                                     pbr.baseColorFactor[2], pbr.baseColorFactor[3]);
    }
    if (pbr.baseColorTexture.index >= 0) {
      if (pbr.baseColorTexture.index >= static_cast<int>(model.textures.size())) {
        reader.Fail("material '", mat.name, "': texture index out of range");
      }
      const int source = model.textures[pbr.baseColorTexture.index].source;
      if (source < 0 || source >= static_cast<int>(rig.textures.size())) {
        reader.Fail("material '", mat.name, "': texture without a valid image");
      }
      m.texture = source;
    }
    rig.materials.push_back(m);
    material_texcoord.push_back(pbr.baseColorTexture.texCoord);
  }
  const int default_material = static_cast<int>(rig.materials.size());
  rig.materials.push_back(RigMaterial{});
  material_texcoord.push_back(0);

  // Scene traversal order: nodes of the default scene (or all roots).
  std::vector<int> roots;
  const int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
  if (scene < static_cast<int>(model.scenes.size())) {
    roots = model.scenes[scene].nodes;
  } else {
    for (int i = 0; i < num_nodes; ++i) {
      if (rig.nodes[i].parent < 0) roots.push_back(i);
    }
  }
  std::vector<int> order;
  std::function<void(int)> visit = [&](int i) {
    if (i < 0 || i >= num_nodes) reader.Fail("scene refers to a missing node ", i);
    order.push_back(i);
    for (int c : model.nodes[i].children) visit(c);
  };
  for (int r : roots) visit(r);

  std::map<int, std::vector<int>> skin_influences;  // skin -> influence per joint
  auto influences_of_skin = [&](int s) -> const std::vector<int>& {
    auto it = skin_influences.find(s);
    if (it != skin_influences.end()) return it->second;
    if (s < 0 || s >= static_cast<int>(model.skins.size())) reader.Fail("bad skin index ", s);
    const tinygltf::Skin& skin = model.skins[s];
    Eigen::MatrixXd ibm;
    if (skin.inverseBindMatrices >= 0) {
      ibm = reader.ReadFloats(skin.inverseBindMatrices, "skin inverseBindMatrices");
      if (ibm.rows() != 16 || ibm.cols() != static_cast<int>(skin.joints.size())) {
        reader.Fail("skin ", s, ": expected one MAT4 inverse bind matrix per joint");
      }
    }
    std::vector<int> ids;
    for (size_t j = 0; j < skin.joints.size(); ++j) {
      RigInfluence inf;
      inf.node = skin.joints[j];
      if (inf.node < 0 || inf.node >= num_nodes) reader.Fail("skin ", s, ": missing joint node");
      if (ibm.size() > 0) {
        for (int k = 0; k < 16; ++k) inf.inverse_bind(k % 4, k / 4) = ibm(k, j);
      }
      ids.push_back(static_cast<int>(rig.influences.size()));
      rig.influences.push_back(inf);
    }
    return skin_influences[s] = ids;
  };

  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Vector3f> colors;
  std::vector<Eigen::Vector2f> uvs;
  std::vector<std::array<int, kMaxVertexInfluences>> vinf;
  std::vector<std::array<float, kMaxVertexInfluences>> vw;
  std::vector<Eigen::Vector3i> faces;
  std::vector<int> face_material;
  bool any_uv = false;

  for (int node_index : order) {
    const tinygltf::Node& n = model.nodes[node_index];
    if (n.mesh < 0) continue;
    const tinygltf::Mesh& mesh = model.meshes[n.mesh];
    const bool skinned = n.skin >= 0;
    int rigid_influence = -1;
    if (!skinned) {
      RigInfluence inf;
      inf.node = node_index;
      inf.inverse_bind = rest_global[node_index].inverse();
      rigid_influence = static_cast<int>(rig.influences.size());
      rig.influences.push_back(inf);
    }
    const Eigen::Matrix4d to_rest = skinned ? Eigen::Matrix4d::Identity() : rest_global[node_index];
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        LOG(WARNING) << path << ": mesh '" << mesh.name << "' primitive " << pi
                     << " is not made of triangles; skipped";
        continue;
      }
      auto attr = [&](const std::string& name) {
        auto it = prim.attributes.find(name);
        return it == prim.attributes.end() ? -1 : it->second;
      };
      if (attr("POSITION") < 0) reader.Fail("mesh '", mesh.name, "': primitive without POSITION");
      const Eigen::MatrixXd pos = reader.ReadFloats(attr("POSITION"), "POSITION");
      if (pos.rows() != 3) reader.Fail("POSITION must be VEC3");
      const int count = static_cast<int>(pos.cols());
      const int base = static_cast<int>(positions.size());
      for (int i = 0; i < count; ++i) {
        positions.push_back((to_rest * pos.col(i).homogeneous()).head<3>());
      }
      // Colours.
      if (attr("COLOR_0") >= 0) {
        const Eigen::MatrixXd col = reader.ReadFloats(attr("COLOR_0"), "COLOR_0");
        if (col.cols() != count || col.rows() < 3) reader.Fail("COLOR_0 size mismatch");
        for (int i = 0; i < count; ++i) {
          Eigen::Vector3f c;
          for (int k = 0; k < 3; ++k) {
            c[k] = static_cast<float>(std::pow(std::clamp(col(k, i), 0.0, 1.0), 1 / 2.2));
          }
          colors.push_back(c);
        }
      } else {
        for (int i = 0; i < count; ++i) colors.emplace_back(1, 1, 1);
      }
      // UVs of the material's base colour texture.
      const int material = prim.material >= 0 ? prim.material : default_material;
      if (material >= static_cast<int>(rig.materials.size())) reader.Fail("bad material index");
      const std::string uv_name = "TEXCOORD_" + std::to_string(material_texcoord[material]);
      if (attr(uv_name) >= 0) {
        const Eigen::MatrixXd uv = reader.ReadFloats(attr(uv_name), uv_name.c_str());
        if (uv.cols() != count || uv.rows() != 2) reader.Fail(uv_name, " size mismatch");
        for (int i = 0; i < count; ++i) uvs.push_back(uv.col(i).cast<float>());
        any_uv = true;
      } else {
        if (rig.materials[material].texture >= 0) {
          reader.Fail("mesh '", mesh.name, "': textured material but no ", uv_name);
        }
        for (int i = 0; i < count; ++i) uvs.emplace_back(0, 0);
      }
      // Skinning.
      for (int i = 0; i < count; ++i) {
        std::array<int, kMaxVertexInfluences> ids;
        std::array<float, kMaxVertexInfluences> ws;
        ids.fill(-1);
        ws.fill(0);
        if (!skinned) {
          ids[0] = rigid_influence;
          ws[0] = 1;
        }
        vinf.push_back(ids);
        vw.push_back(ws);
      }
      if (skinned) {
        const std::vector<int>& skin_ids = influences_of_skin(n.skin);
        std::vector<std::pair<int, double>> pairs;
        std::vector<Eigen::MatrixXi> joints;
        std::vector<Eigen::MatrixXd> weights;
        for (int set = 0; set < 2; ++set) {
          const int j = attr("JOINTS_" + std::to_string(set));
          const int w = attr("WEIGHTS_" + std::to_string(set));
          if (j < 0 || w < 0) break;
          joints.push_back(reader.ReadInts(j, "JOINTS"));
          weights.push_back(reader.ReadFloats(w, "WEIGHTS"));
          if (joints.back().rows() != 4 || weights.back().rows() != 4 ||
              joints.back().cols() != count || weights.back().cols() != count) {
            reader.Fail("mesh '", mesh.name, "': JOINTS/WEIGHTS must be VEC4 per vertex");
          }
        }
        if (joints.empty())
          reader.Fail("mesh '", mesh.name, "': skinned node without JOINTS_0/WEIGHTS_0");
        for (int i = 0; i < count; ++i) {
          pairs.clear();
          for (size_t set = 0; set < joints.size(); ++set) {
            for (int k = 0; k < 4; ++k) {
              const double w = weights[set](k, i);
              if (w <= 0) continue;
              const int jj = joints[set](k, i);
              if (jj < 0 || jj >= static_cast<int>(skin_ids.size())) {
                reader.Fail("mesh '", mesh.name, "': joint index ", jj, " out of range");
              }
              pairs.emplace_back(skin_ids[jj], w);
            }
          }
          double sum = 0;
          for (const auto& p : pairs) sum += p.second;
          if (!(sum > 0)) reader.Fail("mesh '", mesh.name, "': vertex ", i, " has no skin weight");
          for (size_t k = 0; k < pairs.size(); ++k) {
            vinf[base + i][k] = pairs[k].first;
            vw[base + i][k] = static_cast<float>(pairs[k].second / sum);
          }
        }
      }
      // Morph targets.
      if (!prim.targets.empty()) {
        RigMorphGroup group;
        group.node = node_index;
        for (int i = 0; i < count; ++i) group.vertices.push_back(base + i);
        for (const auto& target : prim.targets) {
          auto it = target.find("POSITION");
          Eigen::Matrix3Xd delta = Eigen::Matrix3Xd::Zero(3, count);
          if (it != target.end()) {
            const Eigen::MatrixXd d = reader.ReadFloats(it->second, "morph target POSITION");
            if (d.rows() != 3 || d.cols() != count) reader.Fail("morph target size mismatch");
            delta = to_rest.topLeftCorner<3, 3>() * d;
          }
          group.deltas.push_back(delta);
        }
        if (rig.nodes[node_index].morph_weights.size() == 0) {
          rig.nodes[node_index].morph_weights = Eigen::VectorXd::Zero(prim.targets.size());
        }
        rig.morph_groups.push_back(std::move(group));
      }
      // Faces.
      std::vector<int> idx;
      if (prim.indices >= 0) {
        const Eigen::MatrixXi ind = reader.ReadInts(prim.indices, "indices");
        idx.assign(ind.data(), ind.data() + ind.size());
      } else {
        for (int i = 0; i < count; ++i) idx.push_back(i);
      }
      for (int i : idx) {
        if (i < 0 || i >= count) reader.Fail("mesh '", mesh.name, "': index ", i, " out of range");
      }
      auto add_face = [&](int a, int b, int c) {
        if (a == b || b == c || a == c) return;
        faces.emplace_back(base + a, base + b, base + c);
        face_material.push_back(material);
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
  }
  if (faces.empty()) reader.Fail("no triangles in the default scene");

  const int v = static_cast<int>(positions.size());
  rig.rest_vertices.resize(3, v);
  rig.vertex_colors.resize(3, v);
  rig.vertex_influences.resize(kMaxVertexInfluences, v);
  rig.vertex_weights.resize(kMaxVertexInfluences, v);
  if (any_uv) rig.uvs.resize(2, v);
  for (int i = 0; i < v; ++i) {
    rig.rest_vertices.col(i) = positions[i];
    rig.vertex_colors.col(i) = colors[i];
    if (any_uv) rig.uvs.col(i) = uvs[i];
    for (int k = 0; k < kMaxVertexInfluences; ++k) {
      rig.vertex_influences(k, i) = vinf[i][k];
      rig.vertex_weights(k, i) = vw[i][k];
    }
  }
  rig.faces.resize(3, faces.size());
  for (size_t f = 0; f < faces.size(); ++f) rig.faces.col(f) = faces[f];
  rig.face_material = face_material;

  // Animations.
  for (size_t ai = 0; ai < model.animations.size(); ++ai) {
    const tinygltf::Animation& a = model.animations[ai];
    Animation anim;
    anim.name = a.name.empty() ? "animation" + std::to_string(ai) : a.name;
    for (const auto& ch : a.channels) {
      if (ch.sampler < 0 || ch.sampler >= static_cast<int>(a.samplers.size())) {
        reader.Fail("animation '", anim.name, "': channel with a missing sampler");
      }
      if (ch.target_node < 0 || ch.target_node >= num_nodes) continue;  // no target: ignored (spec)
      const tinygltf::AnimationSampler& s = a.samplers[ch.sampler];
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
        reader.Fail("animation '", anim.name, "': unknown target path '", ch.target_path, "'");
      if (s.interpolation == "LINEAR" || s.interpolation.empty())
        c.interpolation = Interpolation::kLinear;
      else if (s.interpolation == "STEP")
        c.interpolation = Interpolation::kStep;
      else if (s.interpolation == "CUBICSPLINE")
        c.interpolation = Interpolation::kCubicSpline;
      else
        reader.Fail("animation '", anim.name, "': unknown interpolation '", s.interpolation, "'");
      const Eigen::MatrixXd in = reader.ReadFloats(s.input, "animation input");
      if (in.rows() != 1) reader.Fail("animation '", anim.name, "': input must be SCALAR");
      c.times.assign(in.data(), in.data() + in.size());
      Eigen::MatrixXd out = reader.ReadFloats(s.output, "animation output");
      if (c.path == ChannelPath::kWeights) {
        // Outputs are scalars: reshape to one column of morph weights per element.
        const int per_key = c.interpolation == Interpolation::kCubicSpline ? 3 : 1;
        const int elements = per_key * c.NumKeys();
        if (elements == 0 || out.size() % elements != 0) {
          reader.Fail("animation '", anim.name, "': weights output size mismatch");
        }
        const Eigen::MatrixXd flat = out;
        out = Eigen::Map<const Eigen::MatrixXd>(flat.data(), out.size() / elements, elements);
      }
      c.values = out;
      const std::string problem = c.Validate();
      if (!problem.empty()) reader.Fail("animation '", anim.name, "': ", problem);
      anim.channels.push_back(std::move(c));
    }
    rig.animations.push_back(std::move(anim));
  }

  const std::string problem = rig.Validate();
  if (!problem.empty()) reader.Fail(problem);
  return rig;
}

}  // namespace banmo::synth
