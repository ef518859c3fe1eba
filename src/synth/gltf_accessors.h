// Reading glTF accessors as Eigen matrices (private to the synth module):
// strided buffer views, every component type (so KHR_mesh_quantization's
// integer positions, normals and texture coordinates), normalised integers,
// accessors without a bufferView (zeros), sparse accessors, and values
// decoded from a KHR_draco_mesh_compression stream (set with SetDecoded).
#pragma once

#include <Eigen/Core>
#include <map>
#include <string>
#include <utility>

#include "banmo/util/error.h"
#include "gltf_document.h"

namespace banmo::synth::internal {

class GltfAccessors {
 public:
  GltfAccessors(const std::string& path, const tinygltf::Model& model) : path_(path), m_(model) {}

  // Accessor `index` as a (components x count) matrix of doubles, with
  // normalised integer types mapped to [0, 1] / [-1, 1] as the spec says.
  Eigen::MatrixXd ReadFloats(int index, const char* what) const;
  // Integer accessor (indices, joints) as a (components x count) matrix.
  Eigen::MatrixXi ReadInts(int index, const char* what) const;

  // Replaces the data of accessor `index` by `raw` (components x count,
  // integer types as their integer values, before normalisation): the
  // attributes and indices of a Draco-compressed primitive.
  void SetDecoded(int index, Eigen::MatrixXd raw);

  const tinygltf::Accessor& Accessor(int index, const char* what) const;
  const std::string& path() const { return path_; }

  template <typename... Args>
  [[noreturn]] void Fail(Args&&... args) const {
    ThrowInputError(path_, ": ", std::forward<Args>(args)...);
  }

 private:
  // The raw (not normalised) values of accessor `index`.
  Eigen::MatrixXd ReadRaw(int index, const char* what) const;
  // `count` elements of `comps` components of `component_type` from buffer
  // view `view` at `byte_offset` (stride from the view, or packed).
  Eigen::MatrixXd ReadView(int view, std::size_t byte_offset, int component_type, int comps,
                           std::size_t count, const char* what) const;
  void ApplySparse(const tinygltf::Accessor& a, const char* what, Eigen::MatrixXd* values) const;

  std::string path_;
  const tinygltf::Model& m_;
  std::map<int, Eigen::MatrixXd> decoded_;
};

}  // namespace banmo::synth::internal
