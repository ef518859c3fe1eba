#include "gltf_accessors.h"

#include <algorithm>
#include <cstdint>
#include <cstring>

namespace banmo::synth::internal {
namespace {

double ReadComponent(const unsigned char* q, int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float f;
      std::memcpy(&f, q, 4);
      return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return *q;
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return static_cast<signed char>(*q);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t s;
      std::memcpy(&s, q, 2);
      return s;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t s;
      std::memcpy(&s, q, 2);
      return s;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t s;
      std::memcpy(&s, q, 4);
      return s;
    }
    default:
      return 0;  // rejected by the caller
  }
}

bool KnownComponentType(int t) {
  return t == TINYGLTF_COMPONENT_TYPE_FLOAT || t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
         t == TINYGLTF_COMPONENT_TYPE_BYTE || t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ||
         t == TINYGLTF_COMPONENT_TYPE_SHORT || t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
}

// The spec's normalisation of integer components.
double Normalize(double v, int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return v / 255.0;
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return std::max(v / 127.0, -1.0);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return v / 65535.0;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return std::max(v / 32767.0, -1.0);
    default:
      return v;
  }
}

}  // namespace

const tinygltf::Accessor& GltfAccessors::Accessor(int index, const char* what) const {
  if (index < 0 || index >= static_cast<int>(m_.accessors.size())) {
    Fail(what, ": accessor index ", index, " out of range");
  }
  return m_.accessors[index];
}

void GltfAccessors::SetDecoded(int index, Eigen::MatrixXd raw) { decoded_[index] = std::move(raw); }

Eigen::MatrixXd GltfAccessors::ReadFloats(int index, const char* what) const {
  const tinygltf::Accessor& a = Accessor(index, what);
  Eigen::MatrixXd out = ReadRaw(index, what);
  if (a.normalized && a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
    out = out.unaryExpr([&](double v) { return Normalize(v, a.componentType); });
  }
  if (!out.allFinite()) Fail(what, ": accessor ", index, " has NaN/Inf values");
  return out;
}

Eigen::MatrixXi GltfAccessors::ReadInts(int index, const char* what) const {
  const tinygltf::Accessor& a = Accessor(index, what);
  if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
    Fail(what, ": accessor ", index, " must have an integer component type");
  }
  return ReadRaw(index, what).cast<int>();
}

Eigen::MatrixXd GltfAccessors::ReadRaw(int index, const char* what) const {
  const tinygltf::Accessor& a = Accessor(index, what);
  const int comps = tinygltf::GetNumComponentsInType(a.type);
  if (comps <= 0 || !KnownComponentType(a.componentType)) {
    Fail(what, ": accessor ", index, " has an unsupported type or component type");
  }
  const auto it = decoded_.find(index);
  if (it != decoded_.end()) return it->second;
  Eigen::MatrixXd out;
  if (a.bufferView < 0) {
    // No bufferView: zeros (the spec), unless sparse values replace them.
    out = Eigen::MatrixXd::Zero(comps, a.count);
  } else {
    out = ReadView(a.bufferView, a.byteOffset, a.componentType, comps, a.count, what);
  }
  if (a.sparse.isSparse) ApplySparse(a, what, &out);
  return out;
}

Eigen::MatrixXd GltfAccessors::ReadView(int view_index, std::size_t byte_offset, int component_type,
                                        int comps, std::size_t count, const char* what) const {
  Eigen::MatrixXd out(comps, count);
  if (count == 0) return out;
  if (view_index < 0 || view_index >= static_cast<int>(m_.bufferViews.size())) {
    Fail(what, ": accessor refers to a missing bufferView ", view_index);
  }
  const tinygltf::BufferView& view = m_.bufferViews[view_index];
  if (view.buffer < 0 || view.buffer >= static_cast<int>(m_.buffers.size())) {
    Fail(what, ": bufferView ", view_index, " without a valid buffer");
  }
  const std::vector<unsigned char>& data = m_.buffers[view.buffer].data;
  const int csize = tinygltf::GetComponentSizeInBytes(component_type);
  const std::size_t elem = static_cast<std::size_t>(comps) * csize;
  const std::size_t stride = view.byteStride > 0 ? view.byteStride : elem;
  const std::size_t begin = view.byteOffset + byte_offset;
  const std::size_t last_end = begin + stride * (count - 1) + elem;
  if (last_end > view.byteOffset + view.byteLength || last_end > data.size()) {
    Fail(what, ": accessor reads past the end of bufferView ", view_index);
  }
  for (std::size_t i = 0; i < count; ++i) {
    const unsigned char* p = data.data() + begin + stride * i;
    for (int c = 0; c < comps; ++c) out(c, i) = ReadComponent(p + c * csize, component_type);
  }
  return out;
}

void GltfAccessors::ApplySparse(const tinygltf::Accessor& a, const char* what,
                                Eigen::MatrixXd* values) const {
  const int n = a.sparse.count;
  if (n <= 0 || n > static_cast<int>(a.count)) {
    Fail(what, ": sparse accessor with ", n, " entries for ", a.count, " elements");
  }
  const int index_type = a.sparse.indices.componentType;
  if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    Fail(what, ": sparse indices must be unsigned integers");
  }
  // Sparse index and value views are tightly packed (the spec forbids a stride).
  const Eigen::MatrixXd indices =
      ReadView(a.sparse.indices.bufferView, a.sparse.indices.byteOffset, index_type, 1, n, what);
  const Eigen::MatrixXd replaced =
      ReadView(a.sparse.values.bufferView, a.sparse.values.byteOffset, a.componentType,
               static_cast<int>(values->rows()), n, what);
  for (int k = 0; k < n; ++k) {
    const double i = indices(0, k);
    if (i < 0 || i >= static_cast<double>(a.count)) {
      Fail(what, ": sparse index ", i, " out of range (", a.count, " elements)");
    }
    values->col(static_cast<Eigen::Index>(i)) = replaced.col(k);
  }
}

}  // namespace banmo::synth::internal
