#include "banmo/gltf/validate.h"

// Debian's libtinygltf-dev is a shared library (stb and the JSON parser
// compiled in): no TINYGLTF_IMPLEMENTATION anywhere in this project.
#include <tiny_gltf.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>
#include <utility>

#include "banmo/util/error.h"

namespace banmo {

void GltfValidationOptions::Check() const {
  if (!(weight_sum_tolerance > 0)) {
    ThrowInputError("weight_sum_tolerance: expected > 0, got ", weight_sum_tolerance);
  }
  if (!(unit_tolerance > 0)) ThrowInputError("unit_tolerance: expected > 0, got ", unit_tolerance);
  if (max_problems < 1) ThrowInputError("max_problems: expected >= 1, got ", max_problems);
}

namespace {

int ComponentBytes(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return -1;
  }
}

class Validator {
 public:
  Validator(const tinygltf::Model& m, const GltfValidationOptions& o) : m_(m), o_(o) {}

  std::vector<std::string> Run() {
    CheckBufferViews();
    if (Full()) return problems_;
    CheckNodes();
    if (Full()) return problems_;
    CheckSkins();
    if (Full()) return problems_;
    CheckMeshes();
    if (Full()) return problems_;
    CheckAnimations();
    return problems_;
  }

 private:
  template <typename... Args>
  void Add(Args&&... args) {
    if (Full()) return;
    std::ostringstream os;
    (os << ... << std::forward<Args>(args));
    problems_.push_back(os.str());
  }
  bool Full() const { return static_cast<int>(problems_.size()) >= o_.max_problems; }

  void CheckBufferViews() {
    for (size_t i = 0; i < m_.bufferViews.size(); ++i) {
      const tinygltf::BufferView& v = m_.bufferViews[i];
      if (v.buffer < 0 || v.buffer >= static_cast<int>(m_.buffers.size())) {
        Add("bufferViews[", i, "]: buffer ", v.buffer, " out of range");
      } else if (v.byteOffset + v.byteLength > m_.buffers[v.buffer].data.size()) {
        Add("bufferViews[", i, "]: bytes ", v.byteOffset, "..", v.byteOffset + v.byteLength,
            " beyond buffer ", v.buffer, " (", m_.buffers[v.buffer].data.size(), " bytes)");
      }
      if (v.byteStride != 0 && (v.byteStride < 4 || v.byteStride > 252 || v.byteStride % 4 != 0)) {
        Add("bufferViews[", i, "]: byteStride ", v.byteStride, " not a multiple of 4 in 4..252");
      }
    }
  }

  // Reads accessor `index` as (components x count) doubles (normalised
  // integers mapped to [0, 1] / [-1, 1] when `normalize`); false (with a
  // problem recorded) if it cannot be read.
  bool Read(int index, const std::string& what, Eigen::MatrixXd* out, bool normalize = true) {
    if (index < 0 || index >= static_cast<int>(m_.accessors.size())) {
      Add(what, ": accessor ", index, " out of range");
      return false;
    }
    const tinygltf::Accessor& a = m_.accessors[index];
    const std::string name = what + " (accessors[" + std::to_string(index) + "])";
    if (a.sparse.isSparse) {
      Add(name, ": sparse accessors are not supported");
      return false;
    }
    const int comps = tinygltf::GetNumComponentsInType(a.type);
    const int bytes = ComponentBytes(a.componentType);
    if (comps <= 0 || bytes <= 0) {
      Add(name, ": bad type or componentType");
      return false;
    }
    if (a.count < 1) {
      Add(name, ": count must be >= 1");
      return false;
    }
    if (a.bufferView < 0 || a.bufferView >= static_cast<int>(m_.bufferViews.size())) {
      Add(name, ": bufferView ", a.bufferView, " out of range");
      return false;
    }
    const tinygltf::BufferView& v = m_.bufferViews[a.bufferView];
    if (v.buffer < 0 || v.buffer >= static_cast<int>(m_.buffers.size()) ||
        v.byteOffset + v.byteLength > m_.buffers[v.buffer].data.size()) {
      return false;  // reported by CheckBufferViews
    }
    // Matrices of 1- and 2-byte components have column padding; only the
    // unpadded cases occur in skinned meshes and are read here.
    if ((a.type == TINYGLTF_TYPE_MAT2 && bytes == 1) ||
        (a.type == TINYGLTF_TYPE_MAT3 && bytes < 4)) {
      Add(name, ": padded matrix layouts are not supported");
      return false;
    }
    const size_t element = static_cast<size_t>(comps) * bytes;
    const size_t stride = v.byteStride != 0 ? v.byteStride : element;
    if (stride < element) {
      Add(name, ": byteStride ", stride, " < element size ", element);
      return false;
    }
    if ((v.byteOffset + a.byteOffset) % bytes != 0) {
      Add(name, ": offset not aligned to its component size ", bytes);
      return false;
    }
    if (a.byteOffset + stride * (a.count - 1) + element > v.byteLength) {
      Add(name, ": ", a.count, " elements do not fit in bufferViews[", a.bufferView, "] (",
          v.byteLength, " bytes)");
      return false;
    }
    const unsigned char* base = m_.buffers[v.buffer].data.data() + v.byteOffset + a.byteOffset;
    out->resize(comps, static_cast<Eigen::Index>(a.count));
    for (size_t i = 0; i < a.count; ++i) {
      const unsigned char* e = base + i * stride;
      for (int c = 0; c < comps; ++c) {
        const unsigned char* p = e + static_cast<size_t>(c) * bytes;
        double value = 0;
        switch (a.componentType) {
          case TINYGLTF_COMPONENT_TYPE_FLOAT: {
            float f;
            std::memcpy(&f, p, 4);
            value = f;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
            value = *p;
            if (normalize && a.normalized) value /= 255.0;
            break;
          case TINYGLTF_COMPONENT_TYPE_BYTE: {
            int8_t s;
            std::memcpy(&s, p, 1);
            value = (normalize && a.normalized) ? std::max(s / 127.0, -1.0) : s;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            uint16_t s;
            std::memcpy(&s, p, 2);
            value = (normalize && a.normalized) ? s / 65535.0 : s;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_SHORT: {
            int16_t s;
            std::memcpy(&s, p, 2);
            value = (normalize && a.normalized) ? std::max(s / 32767.0, -1.0) : s;
            break;
          }
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
            uint32_t s;
            std::memcpy(&s, p, 4);
            value = s;
            break;
          }
        }
        (*out)(c, static_cast<Eigen::Index>(i)) = value;
      }
    }
    if (!out->allFinite()) {
      Add(name, ": non-finite values");
      return false;
    }
    return true;
  }

  bool ValidNode(int n) const { return n >= 0 && n < static_cast<int>(m_.nodes.size()); }

  void CheckNodes() {
    for (size_t s = 0; s < m_.scenes.size(); ++s) {
      for (int n : m_.scenes[s].nodes) {
        if (!ValidNode(n)) Add("scenes[", s, "]: node ", n, " out of range");
      }
    }
    if (m_.defaultScene >= static_cast<int>(m_.scenes.size())) {
      Add("scene ", m_.defaultScene, " out of range");
    }
    std::vector<int> parent(m_.nodes.size(), -1);
    for (size_t i = 0; i < m_.nodes.size(); ++i) {
      const tinygltf::Node& n = m_.nodes[i];
      const std::string name = "nodes[" + std::to_string(i) + "]";
      for (int c : n.children) {
        if (!ValidNode(c) || c == static_cast<int>(i)) {
          Add(name, ": child ", c, " out of range or itself");
        } else if (parent[c] != -1) {
          Add("nodes[", c, "] has two parents (", parent[c], " and ", i, ")");
        } else {
          parent[c] = static_cast<int>(i);
        }
      }
      if (n.mesh >= static_cast<int>(m_.meshes.size()))
        Add(name, ": mesh ", n.mesh, " out of range");
      if (n.skin >= static_cast<int>(m_.skins.size()))
        Add(name, ": skin ", n.skin, " out of range");
      if (n.skin >= 0 && n.mesh < 0) Add(name, ": skin without mesh");
      if (!n.matrix.empty() && (n.matrix.size() != 16 || !n.rotation.empty() ||
                                !n.translation.empty() || !n.scale.empty())) {
        Add(name, ": matrix must have 16 values and exclude TRS");
      }
      if (!n.translation.empty() && n.translation.size() != 3) Add(name, ": translation size");
      if (!n.scale.empty() && n.scale.size() != 3) Add(name, ": scale size");
      if (!n.rotation.empty()) {
        if (n.rotation.size() != 4) {
          Add(name, ": rotation size");
        } else {
          const double norm =
              Eigen::Vector4d(n.rotation[0], n.rotation[1], n.rotation[2], n.rotation[3]).norm();
          if (!(std::abs(norm - 1) <= o_.unit_tolerance)) {
            Add(name, ": rotation not a unit quaternion (norm ", norm, ")");
          }
        }
      }
    }
    // Cycles: walking up from any node must reach a root within N steps.
    for (size_t i = 0; i < m_.nodes.size(); ++i) {
      int p = static_cast<int>(i);
      size_t steps = 0;
      while (p != -1 && steps <= m_.nodes.size()) {
        p = parent[p];
        ++steps;
      }
      if (p != -1) {
        Add("nodes[", i, "]: part of a cycle");
        break;
      }
    }
  }

  void CheckSkins() {
    for (size_t s = 0; s < m_.skins.size(); ++s) {
      const tinygltf::Skin& skin = m_.skins[s];
      const std::string name = "skins[" + std::to_string(s) + "]";
      if (skin.joints.empty()) Add(name, ": no joints");
      std::vector<bool> seen(m_.nodes.size(), false);
      for (int j : skin.joints) {
        if (!ValidNode(j)) {
          Add(name, ": joint node ", j, " out of range");
        } else if (seen[j]) {
          Add(name, ": joint node ", j, " listed twice");
        } else {
          seen[j] = true;
        }
      }
      if (skin.skeleton != -1 && !ValidNode(skin.skeleton)) {
        Add(name, ": skeleton node ", skin.skeleton, " out of range");
      }
      if (skin.inverseBindMatrices < 0) continue;  // identity matrices (spec default)
      const std::string what = name + " inverseBindMatrices";
      const tinygltf::Accessor* a = AccessorOrNull(skin.inverseBindMatrices);
      if (a != nullptr &&
          (a->type != TINYGLTF_TYPE_MAT4 || a->componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)) {
        Add(what, ": expected float MAT4");
        continue;
      }
      Eigen::MatrixXd m;
      if (!Read(skin.inverseBindMatrices, what, &m)) continue;
      if (m.cols() != static_cast<Eigen::Index>(skin.joints.size())) {
        Add(what, ": ", m.cols(), " matrices for ", skin.joints.size(), " joints");
      }
      for (Eigen::Index j = 0; j < m.cols(); ++j) {
        // Column-major: the last row is elements 3, 7, 11, 15.
        if (m(3, j) != 0 || m(7, j) != 0 || m(11, j) != 0 || m(15, j) != 1) {
          Add(what, " matrix ", j, ": last row is not 0 0 0 1");
          break;
        }
      }
    }
  }

  const tinygltf::Accessor* AccessorOrNull(int index) const {
    if (index < 0 || index >= static_cast<int>(m_.accessors.size())) return nullptr;
    return &m_.accessors[index];
  }

  void CheckMeshes() {
    // Joint count of the skin(s) each mesh is used with (min over nodes).
    std::map<int, int> mesh_joints;
    for (const tinygltf::Node& n : m_.nodes) {
      if (n.mesh < 0 || n.mesh >= static_cast<int>(m_.meshes.size())) continue;
      if (n.skin < 0 || n.skin >= static_cast<int>(m_.skins.size())) continue;
      const int joints = static_cast<int>(m_.skins[n.skin].joints.size());
      auto it = mesh_joints.find(n.mesh);
      if (it == mesh_joints.end() || joints < it->second) mesh_joints[n.mesh] = joints;
    }
    for (size_t mi = 0; mi < m_.meshes.size(); ++mi) {
      for (size_t pi = 0; pi < m_.meshes[mi].primitives.size(); ++pi) {
        const std::string name =
            "meshes[" + std::to_string(mi) + "].primitives[" + std::to_string(pi) + "]";
        auto it = mesh_joints.find(static_cast<int>(mi));
        CheckPrimitive(m_.meshes[mi].primitives[pi], name,
                       it == mesh_joints.end() ? -1 : it->second);
      }
    }
  }

  void CheckPrimitive(const tinygltf::Primitive& p, const std::string& name, int joint_count) {
    const auto position = p.attributes.find("POSITION");
    if (position == p.attributes.end()) {
      Add(name, ": no POSITION");
      return;
    }
    long vertices = -1;
    for (const auto& [attribute, index] : p.attributes) {
      const tinygltf::Accessor* a = AccessorOrNull(index);
      if (a == nullptr) {
        Add(name, " ", attribute, ": accessor ", index, " out of range");
        return;
      }
      if (vertices == -1) vertices = static_cast<long>(a->count);
      if (static_cast<long>(a->count) != vertices) {
        Add(name, ": attribute ", attribute, " has ", a->count, " elements, others ", vertices);
      }
    }
    // POSITION: float VEC3 with exact bounds.
    {
      const tinygltf::Accessor& a = m_.accessors[position->second];
      const std::string what = name + " POSITION";
      Eigen::MatrixXd x;
      if (a.type != TINYGLTF_TYPE_VEC3 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
        Add(what, ": expected float VEC3");
      } else if (Read(position->second, what, &x)) {
        if (a.minValues.size() != 3 || a.maxValues.size() != 3) {
          Add(what, ": min/max missing (required for POSITION)");
        } else {
          const Eigen::Vector3d lo = x.rowwise().minCoeff(), hi = x.rowwise().maxCoeff();
          for (int c = 0; c < 3; ++c) {
            // The data are floats, so their bounds are float values; a bound
            // is correct if it rounds to exactly that float.
            if (static_cast<float>(a.minValues[c]) != static_cast<float>(lo[c]) ||
                static_cast<float>(a.maxValues[c]) != static_cast<float>(hi[c])) {
              Add(what, ": min/max [", a.minValues[c], ", ", a.maxValues[c], "] on axis ", c,
                  " but the data span [", lo[c], ", ", hi[c], "]");
              break;
            }
          }
        }
      }
    }
    if (auto it = p.attributes.find("NORMAL"); it != p.attributes.end()) {
      Eigen::MatrixXd nrm;
      const std::string what = name + " NORMAL";
      if (Read(it->second, what, &nrm)) {
        if (nrm.rows() != 3) {
          Add(what, ": expected VEC3");
        } else {
          for (Eigen::Index i = 0; i < nrm.cols(); ++i) {
            if (!(std::abs(nrm.col(i).norm() - 1) <= o_.unit_tolerance)) {
              Add(what, " vertex ", i, ": not unit length (", nrm.col(i).norm(), ")");
              break;
            }
          }
        }
      }
    }
    for (const char* attribute : {"COLOR_0", "TEXCOORD_0"}) {
      if (auto it = p.attributes.find(attribute); it != p.attributes.end()) {
        Eigen::MatrixXd unused;
        Read(it->second, name + " " + attribute, &unused);
      }
    }
    if (p.indices >= 0) {
      const tinygltf::Accessor* a = AccessorOrNull(p.indices);
      const std::string what = name + " indices";
      Eigen::MatrixXd idx;
      if (a == nullptr) {
        Add(what, ": accessor ", p.indices, " out of range");
      } else if (a->type != TINYGLTF_TYPE_SCALAR ||
                 (a->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                  a->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                  a->componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
        Add(what, ": expected unsigned integer SCALAR");
      } else if (Read(p.indices, what, &idx, /*normalize=*/false)) {
        const int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
        if (mode == TINYGLTF_MODE_TRIANGLES && idx.cols() % 3 != 0) {
          Add(what, ": ", idx.cols(), " indices, not a multiple of 3");
        }
        const double max_index = idx.maxCoeff();
        if (max_index >= vertices) {
          Add(what, ": index ", max_index, " >= vertex count ", vertices);
        }
      }
    }
    // Skinning attributes.
    const auto joints = p.attributes.find("JOINTS_0");
    const auto weights = p.attributes.find("WEIGHTS_0");
    if ((joints == p.attributes.end()) != (weights == p.attributes.end())) {
      Add(name, ": JOINTS_0 and WEIGHTS_0 must come together");
      return;
    }
    if (joints == p.attributes.end()) return;
    if (joint_count < 0) {
      Add(name, ": has JOINTS_0 but no node uses its mesh with a skin");
      return;
    }
    const tinygltf::Accessor& ja = m_.accessors[joints->second];
    const tinygltf::Accessor& wa = m_.accessors[weights->second];
    if (ja.type != TINYGLTF_TYPE_VEC4 ||
        (ja.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
         ja.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)) {
      Add(name, " JOINTS_0: expected unsigned byte/short VEC4");
      return;
    }
    if (wa.type != TINYGLTF_TYPE_VEC4 ||
        !(wa.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
          (wa.normalized && (wa.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                             wa.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)))) {
      Add(name, " WEIGHTS_0: expected float (or normalised unsigned byte/short) VEC4");
      return;
    }
    Eigen::MatrixXd j, w;
    if (!Read(joints->second, name + " JOINTS_0", &j, /*normalize=*/false) ||
        !Read(weights->second, name + " WEIGHTS_0", &w)) {
      return;
    }
    for (Eigen::Index i = 0; i < j.cols() && i < w.cols(); ++i) {
      for (int k = 0; k < 4; ++k) {
        if (j(k, i) >= joint_count) {
          Add(name, " JOINTS_0 vertex ", i, ": joint ", j(k, i), " >= skin joint count ",
              joint_count);
          return;
        }
        if (w(k, i) < 0) {
          Add(name, " WEIGHTS_0 vertex ", i, ": negative weight ", w(k, i));
          return;
        }
      }
      const double sum = w.col(i).sum();
      if (!(std::abs(sum - 1) <= o_.weight_sum_tolerance)) {
        Add(name, " WEIGHTS_0 vertex ", i, ": weights sum to ", sum, " (tolerance ",
            o_.weight_sum_tolerance, ")");
        return;
      }
    }
  }

  void CheckAnimations() {
    for (size_t ai = 0; ai < m_.animations.size(); ++ai) {
      const tinygltf::Animation& anim = m_.animations[ai];
      const std::string name = "animations[" + std::to_string(ai) + "] '" + anim.name + "'";
      std::vector<std::string> sampler_paths(anim.samplers.size());
      for (size_t c = 0; c < anim.channels.size(); ++c) {
        const tinygltf::AnimationChannel& ch = anim.channels[c];
        const std::string cname = name + " channels[" + std::to_string(c) + "]";
        if (ch.sampler < 0 || ch.sampler >= static_cast<int>(anim.samplers.size())) {
          Add(cname, ": sampler ", ch.sampler, " out of range");
          continue;
        }
        if (!ValidNode(ch.target_node))
          Add(cname, ": target node ", ch.target_node, " out of range");
        if (ch.target_path != "translation" && ch.target_path != "rotation" &&
            ch.target_path != "scale" && ch.target_path != "weights") {
          Add(cname, ": unknown path '", ch.target_path, "'");
          continue;
        }
        sampler_paths[ch.sampler] = ch.target_path;
      }
      for (size_t s = 0; s < anim.samplers.size(); ++s) {
        CheckSampler(anim.samplers[s], name + " samplers[" + std::to_string(s) + "]",
                     sampler_paths[s]);
      }
    }
  }

  void CheckSampler(const tinygltf::AnimationSampler& s, const std::string& name,
                    const std::string& path) {
    const std::string interpolation = s.interpolation.empty() ? "LINEAR" : s.interpolation;
    if (interpolation != "LINEAR" && interpolation != "STEP" && interpolation != "CUBICSPLINE") {
      Add(name, ": unknown interpolation '", interpolation, "'");
      return;
    }
    const tinygltf::Accessor* in = AccessorOrNull(s.input);
    Eigen::MatrixXd t, out;
    if (in == nullptr) {
      Add(name, ": input accessor ", s.input, " out of range");
      return;
    }
    if (in->type != TINYGLTF_TYPE_SCALAR || in->componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
      Add(name, " input: expected float SCALAR");
      return;
    }
    if (!Read(s.input, name + " input", &t)) return;
    if (in->minValues.size() != 1 || in->maxValues.size() != 1) {
      Add(name, " input: min/max missing (required for animation input)");
    } else if (static_cast<float>(in->minValues[0]) != static_cast<float>(t.minCoeff()) ||
               static_cast<float>(in->maxValues[0]) != static_cast<float>(t.maxCoeff())) {
      Add(name, " input: min/max do not match the data");
    }
    if (t(0, 0) < 0) Add(name, " input: negative time ", t(0, 0));
    for (Eigen::Index k = 1; k < t.cols(); ++k) {
      if (!(t(0, k) > t(0, k - 1))) {
        Add(name, " input: times not strictly increasing at key ", k, " (", t(0, k - 1), ", ",
            t(0, k), ")");
        break;
      }
    }
    if (!Read(s.output, name + " output", &out)) return;
    const Eigen::Index expected = t.cols() * (interpolation == "CUBICSPLINE" ? 3 : 1);
    if (path == "weights") {
      if (out.cols() % expected != 0) Add(name, " output: count not a multiple of the keys");
      return;
    }
    if (out.cols() != expected) {
      Add(name, " output: ", out.cols(), " values for ", t.cols(), " keys (", interpolation, ")");
      return;
    }
    if (path == "rotation") {
      if (out.rows() != 4) {
        Add(name, " output: rotation must be VEC4");
        return;
      }
      for (Eigen::Index k = 0; k < out.cols(); ++k) {
        if (interpolation == "CUBICSPLINE" && k % 3 != 1) continue;  // tangents
        if (!(std::abs(out.col(k).norm() - 1) <= o_.unit_tolerance)) {
          Add(name, " output key ", k, ": rotation not a unit quaternion (norm ", out.col(k).norm(),
              ")");
          return;
        }
      }
    } else if ((path == "translation" || path == "scale") && out.rows() != 3) {
      Add(name, " output: ", path, " must be VEC3");
    }
  }

  const tinygltf::Model& m_;
  const GltfValidationOptions& o_;
  std::vector<std::string> problems_;
};

}  // namespace

std::vector<std::string> ValidateGltf(const tinygltf::Model& gltf,
                                      const GltfValidationOptions& options) {
  options.Check();
  return Validator(gltf, options).Run();
}

void CheckGltfOrThrow(const tinygltf::Model& gltf, const std::string& what,
                      const GltfValidationOptions& options) {
  const std::vector<std::string> problems = ValidateGltf(gltf, options);
  if (problems.empty()) return;
  std::ostringstream os;
  os << what << ": invalid glTF (" << problems.size()
     << (static_cast<int>(problems.size()) >= options.max_problems ? "+" : "")
     << " problems): " << problems[0];
  for (size_t i = 1; i < problems.size() && i < 5; ++i) os << "; " << problems[i];
  throw InputError(os.str());
}

}  // namespace banmo
