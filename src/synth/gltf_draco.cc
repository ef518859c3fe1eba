#include "gltf_draco.h"

#include <draco/compression/decode.h>

#include <cstdint>
#include <memory>
#include <vector>

namespace banmo::synth::internal {
namespace {

// The decoded values of one Draco attribute, per point (components x points),
// as raw values: floats as floats, integers as their integer values.
Eigen::MatrixXd AttributeValues(const draco::Mesh& mesh, const draco::PointAttribute& att) {
  const int comps = att.num_components();
  Eigen::MatrixXd out(comps, mesh.num_points());
  const bool is_float =
      att.data_type() == draco::DT_FLOAT32 || att.data_type() == draco::DT_FLOAT64;
  std::vector<double> f(comps);
  std::vector<int64_t> i(comps);
  for (draco::PointIndex p(0); p < mesh.num_points(); ++p) {
    const draco::AttributeValueIndex v = att.mapped_index(p);
    if (is_float) {
      att.ConvertValue<double>(v, static_cast<int8_t>(comps), f.data());
      for (int c = 0; c < comps; ++c) out(c, p.value()) = f[c];
    } else {
      att.ConvertValue<int64_t>(v, static_cast<int8_t>(comps), i.data());
      for (int c = 0; c < comps; ++c) out(c, p.value()) = static_cast<double>(i[c]);
    }
  }
  return out;
}

}  // namespace

bool DecodeDracoPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& prim,
                          const std::string& mesh_name, GltfAccessors* accessors,
                          std::vector<int>* indices) {
  const auto ext = prim.extensions.find(kDracoExtension);
  if (ext == prim.extensions.end()) return false;
  const std::string where = "mesh '" + mesh_name + "': " + kDracoExtension;
  const tinygltf::Value& draco_ext = ext->second;
  if (!draco_ext.IsObject() || !draco_ext.Get("bufferView").IsNumber() ||
      !draco_ext.Get("attributes").IsObject()) {
    accessors->Fail(where, ": expected an object with bufferView and attributes");
  }
  const int view_index = draco_ext.Get("bufferView").GetNumberAsInt();
  if (view_index < 0 || view_index >= static_cast<int>(model.bufferViews.size())) {
    accessors->Fail(where, ": bufferView ", view_index, " out of range");
  }
  const tinygltf::BufferView& view = model.bufferViews[view_index];
  if (view.buffer < 0 || view.buffer >= static_cast<int>(model.buffers.size()) ||
      view.byteOffset + view.byteLength > model.buffers[view.buffer].data.size()) {
    accessors->Fail(where, ": bufferView ", view_index, " lies outside its buffer");
  }
  draco::DecoderBuffer buffer;
  buffer.Init(
      reinterpret_cast<const char*>(model.buffers[view.buffer].data.data()) + view.byteOffset,
      view.byteLength);
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) {
    accessors->Fail(where,
                    ": cannot decode the Draco stream: ", decoded.status().error_msg_string());
  }
  const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
  const int points = static_cast<int>(mesh->num_points());

  const tinygltf::Value& attributes = draco_ext.Get("attributes");
  for (const std::string& name : attributes.Keys()) {
    const auto it = prim.attributes.find(name);
    if (it == prim.attributes.end()) continue;  // compressed but not listed: unused
    const tinygltf::Accessor& a = accessors->Accessor(it->second, name.c_str());
    const int id = attributes.Get(name).GetNumberAsInt();
    const draco::PointAttribute* att = mesh->GetAttributeByUniqueId(static_cast<uint32_t>(id));
    if (att == nullptr)
      accessors->Fail(where, ": no Draco attribute with id ", id, " (", name, ")");
    if (static_cast<int>(a.count) != points ||
        att->num_components() != tinygltf::GetNumComponentsInType(a.type)) {
      accessors->Fail(where, ": ", name, " decodes to ", points, " x ", int(att->num_components()),
                      " values, its accessor declares ", a.count, " x ",
                      tinygltf::GetNumComponentsInType(a.type));
    }
    accessors->SetDecoded(it->second, AttributeValues(*mesh, *att));
  }
  indices->clear();
  for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) indices->push_back(static_cast<int>(mesh->face(f)[k].value()));
  }
  if (prim.indices >= 0) {
    const tinygltf::Accessor& a = accessors->Accessor(prim.indices, "indices");
    if (a.count != indices->size()) {
      accessors->Fail(where, ": ", mesh->num_faces(), " decoded triangles, the indices accessor ",
                      "declares ", a.count, " indices");
    }
    Eigen::MatrixXd values(1, a.count);
    for (std::size_t i = 0; i < indices->size(); ++i) values(0, i) = (*indices)[i];
    accessors->SetDecoded(prim.indices, std::move(values));
  }
  return true;
}

}  // namespace banmo::synth::internal
