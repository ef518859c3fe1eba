// glTF files made at test time (never committed): a tiny skinned, animated,
// textured strip built in code, and Draco-compressed copies of any model
// (libdraco's encoder), to test the loader on what exporters write.
#pragma once

#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

namespace banmo::synth::testing {

// Appends `data` to buffer 0 as a new bufferView (4-byte aligned); returns its index.
template <typename T>
int AddView(tinygltf::Model* m, const std::vector<T>& data) {
  if (m->buffers.empty()) m->buffers.emplace_back();
  std::vector<unsigned char>& buf = m->buffers[0].data;
  while (buf.size() % 4 != 0) buf.push_back(0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = buf.size();
  view.byteLength = data.size() * sizeof(T);
  const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
  buf.insert(buf.end(), bytes, bytes + view.byteLength);
  m->bufferViews.push_back(view);
  return static_cast<int>(m->bufferViews.size()) - 1;
}

// Adds an accessor over a new bufferView holding `data`; returns its index.
template <typename T>
int AddAccessor(tinygltf::Model* m, const std::vector<T>& data, int type, int component_type,
                bool normalized = false) {
  tinygltf::Accessor a;
  a.bufferView = AddView(m, data);
  a.type = type;
  a.componentType = component_type;
  a.normalized = normalized;
  a.count = data.size() / tinygltf::GetNumComponentsInType(type);
  m->accessors.push_back(a);
  return static_cast<int>(m->accessors.size()) - 1;
}

// A strip of 6 vertices (x in {0, 1}, y in {0, 1, 2}) and 4 triangles,
// skinned to two joints (node 0 at the origin, node 1 at y = 1, its child),
// one animation turning node 1 by 90 degrees about z in 1 s, a 4 x 4
// texture with UV = (x, y / 2). Node 2 holds the mesh.
inline tinygltf::Model TinyStrip() {
  tinygltf::Model m;
  m.asset.version = "2.0";
  m.buffers.emplace_back();
  const std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0};
  const std::vector<float> uv = {0, 0, 1, 0, 0, 0.5f, 1, 0.5f, 0, 1, 1, 1};
  const std::vector<uint16_t> idx = {0, 1, 2, 1, 3, 2, 2, 3, 4, 3, 5, 4};
  const std::vector<uint8_t> joints = {0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0,
                                       0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  const std::vector<float> weights = {1,    0,    0, 0, 1, 0, 0, 0, 0.5f, 0.5f, 0, 0,
                                      0.5f, 0.5f, 0, 0, 1, 0, 0, 0, 1,    0,    0, 0};
  std::vector<float> ibm(32, 0.0f);
  for (int j = 0; j < 2; ++j) {
    for (int k = 0; k < 4; ++k) ibm[16 * j + 5 * k] = 1;
  }
  ibm[16 + 13] = -1;  // joint 1: translation (0, -1, 0), column-major
  tinygltf::Primitive prim;
  prim.attributes["POSITION"] =
      AddAccessor(&m, pos, TINYGLTF_TYPE_VEC3, TINYGLTF_COMPONENT_TYPE_FLOAT);
  m.accessors.back().minValues = {0, 0, 0};
  m.accessors.back().maxValues = {1, 2, 0};
  prim.attributes["TEXCOORD_0"] =
      AddAccessor(&m, uv, TINYGLTF_TYPE_VEC2, TINYGLTF_COMPONENT_TYPE_FLOAT);
  prim.attributes["JOINTS_0"] =
      AddAccessor(&m, joints, TINYGLTF_TYPE_VEC4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
  prim.attributes["WEIGHTS_0"] =
      AddAccessor(&m, weights, TINYGLTF_TYPE_VEC4, TINYGLTF_COMPONENT_TYPE_FLOAT);
  prim.indices = AddAccessor(&m, idx, TINYGLTF_TYPE_SCALAR, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
  prim.material = 0;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh mesh;
  mesh.name = "strip";
  mesh.primitives.push_back(prim);
  m.meshes.push_back(mesh);

  tinygltf::Skin skin;
  skin.joints = {0, 1};
  skin.inverseBindMatrices =
      AddAccessor(&m, ibm, TINYGLTF_TYPE_MAT4, TINYGLTF_COMPONENT_TYPE_FLOAT);
  m.skins.push_back(skin);
  tinygltf::Node root, tip, body;
  root.name = "root";
  root.children = {1};
  tip.name = "tip";
  tip.translation = {0, 1, 0};
  body.name = "body";
  body.mesh = 0;
  body.skin = 0;
  m.nodes = {root, tip, body};
  tinygltf::Scene scene;
  scene.nodes = {0, 2};
  m.scenes.push_back(scene);
  m.defaultScene = 0;

  const double h = std::sqrt(0.5);
  tinygltf::AnimationSampler sampler;
  sampler.input = AddAccessor(&m, std::vector<float>{0, 1}, TINYGLTF_TYPE_SCALAR,
                              TINYGLTF_COMPONENT_TYPE_FLOAT);
  m.accessors.back().minValues = {0};
  m.accessors.back().maxValues = {1};
  sampler.output = AddAccessor(&m, std::vector<float>{0, 0, 0, 1, 0, 0, float(h), float(h)},
                               TINYGLTF_TYPE_VEC4, TINYGLTF_COMPONENT_TYPE_FLOAT);
  sampler.interpolation = "LINEAR";
  tinygltf::AnimationChannel channel;
  channel.sampler = 0;
  channel.target_node = 1;
  channel.target_path = "rotation";
  tinygltf::Animation anim;
  anim.name = "bend";
  anim.samplers.push_back(sampler);
  anim.channels.push_back(channel);
  m.animations.push_back(anim);

  tinygltf::Image image;
  image.name = "checker";
  image.width = image.height = 4;
  image.component = 4;
  image.bits = 8;
  image.pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  image.mimeType = "image/png";
  image.uri = "checker.png";
  for (int i = 0; i < 16; ++i) {
    const unsigned char v = ((i + i / 4) % 2) ? 200 : 40;
    image.image.insert(image.image.end(), {v, 100, static_cast<unsigned char>(255 - v), 255});
  }
  m.images.push_back(image);
  tinygltf::Texture texture;
  texture.source = 0;
  m.textures.push_back(texture);
  tinygltf::Material material;
  material.name = "skin";
  material.pbrMetallicRoughness.baseColorTexture.index = 0;
  m.materials.push_back(material);
  return m;
}

// Writes `model` to `path` (.glb: one binary file; .gltf: JSON with the
// buffer in `<stem>.bin` and images as files beside it, or everything as
// data URIs when `embed`).
inline void WriteGltf(tinygltf::Model model, const std::string& path, bool embed = true) {
  const bool binary = path.size() > 4 && path.substr(path.size() - 4) == ".glb";
  if (!binary && !embed) {
    const std::filesystem::path p(path);
    for (auto& b : model.buffers) b.uri = p.stem().string() + ".bin";
    // Images as PNG files beside (tinygltf's writer leaves that to a callback).
    for (const tinygltf::Image& image : model.images) {
      ASSERT_EQ(image.component, 4);
      cv::Mat rgba(image.height, image.width, CV_8UC4,
                   const_cast<unsigned char*>(image.image.data())),
          bgra;
      cv::cvtColor(rgba, bgra, cv::COLOR_RGBA2BGRA);
      ASSERT_TRUE(cv::imwrite((p.parent_path() / image.uri).string(), bgra));
    }
  }
  tinygltf::TinyGLTF writer;
  ASSERT_TRUE(writer.WriteGltfSceneToFile(&model, path, embed || binary, embed || binary,
                                          /*prettyPrint=*/true, binary))
      << path;
}

// Raw component values of a (non-sparse) accessor, one std::vector per element.
inline std::vector<std::vector<double>> ReadRaw(const tinygltf::Model& m, int index) {
  const tinygltf::Accessor& a = m.accessors[index];
  const tinygltf::BufferView& v = m.bufferViews[a.bufferView];
  const int comps = tinygltf::GetNumComponentsInType(a.type);
  const int csize = tinygltf::GetComponentSizeInBytes(a.componentType);
  const std::size_t stride = v.byteStride > 0 ? v.byteStride : std::size_t(comps) * csize;
  std::vector<std::vector<double>> out(a.count, std::vector<double>(comps));
  for (std::size_t i = 0; i < a.count; ++i) {
    const unsigned char* p =
        m.buffers[v.buffer].data.data() + v.byteOffset + a.byteOffset + stride * i;
    for (int c = 0; c < comps; ++c) {
      const unsigned char* q = p + c * csize;
      switch (a.componentType) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: {
          float f;
          std::memcpy(&f, q, 4);
          out[i][c] = f;
          break;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
          out[i][c] = *q;
          break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
          uint16_t s;
          std::memcpy(&s, q, 2);
          out[i][c] = s;
          break;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
          uint32_t s;
          std::memcpy(&s, q, 4);
          out[i][c] = s;
          break;
        }
        default:
          ADD_FAILURE() << "component type " << a.componentType << " not handled by the test";
      }
    }
  }
  return out;
}

// Encodes every triangle primitive of `model` with Draco (positions
// quantised to `position_bits`, texture coordinates to 12 bits, normals to
// 10, everything else lossless) and rewrites it as the
// KHR_draco_mesh_compression extension says: the attribute and index
// accessors lose their bufferView, the compressed stream gets its own.
inline tinygltf::Model DracoCompressed(tinygltf::Model m, int position_bits, bool required = true) {
  for (tinygltf::Mesh& mesh : m.meshes) {
    for (tinygltf::Primitive& prim : mesh.primitives) {
      draco::Mesh dm;
      const int points = static_cast<int>(m.accessors[prim.attributes.begin()->second].count);
      dm.set_num_points(points);
      tinygltf::Value::Object ids;
      for (const auto& [name, index] : prim.attributes) {
        const tinygltf::Accessor& a = m.accessors[index];
        const int comps = tinygltf::GetNumComponentsInType(a.type);
        draco::GeometryAttribute::Type type = draco::GeometryAttribute::GENERIC;
        if (name == "POSITION") type = draco::GeometryAttribute::POSITION;
        if (name == "NORMAL") type = draco::GeometryAttribute::NORMAL;
        if (name.rfind("TEXCOORD_", 0) == 0) type = draco::GeometryAttribute::TEX_COORD;
        if (name.rfind("COLOR_", 0) == 0) type = draco::GeometryAttribute::COLOR;
        const bool is_float = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT;
        const draco::DataType dt = is_float ? draco::DT_FLOAT32 : draco::DT_UINT32;
        draco::GeometryAttribute ga;
        ga.Init(type, nullptr, static_cast<uint8_t>(comps), dt, a.normalized,
                draco::DataTypeLength(dt) * comps, 0);
        const int id = dm.AddAttribute(ga, true, points);
        const auto values = ReadRaw(m, index);
        for (int i = 0; i < points; ++i) {
          float f[16];
          uint32_t u[16];
          for (int c = 0; c < comps; ++c) {
            f[c] = static_cast<float>(values[i][c]);
            u[c] = static_cast<uint32_t>(values[i][c]);
          }
          dm.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(i),
                                              is_float ? static_cast<const void*>(f) : u);
        }
        ids[name] = tinygltf::Value(static_cast<int>(dm.attribute(id)->unique_id()));
        m.accessors[index].bufferView = -1;
        m.accessors[index].byteOffset = 0;
      }
      if (prim.indices < 0) {  // not indexed (the Fox): the vertices in order
        std::vector<uint32_t> order(points);
        for (int i = 0; i < points; ++i) order[i] = i;
        prim.indices =
            AddAccessor(&m, order, TINYGLTF_TYPE_SCALAR, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
      }
      const auto indices = ReadRaw(m, prim.indices);
      for (std::size_t f = 0; f + 2 < indices.size(); f += 3) {
        dm.AddFace({draco::PointIndex(static_cast<uint32_t>(indices[f][0])),
                    draco::PointIndex(static_cast<uint32_t>(indices[f + 1][0])),
                    draco::PointIndex(static_cast<uint32_t>(indices[f + 2][0]))});
      }
      m.accessors[prim.indices].bufferView = -1;
      m.accessors[prim.indices].byteOffset = 0;
      draco::Encoder encoder;
      encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, position_bits);
      encoder.SetAttributeQuantization(draco::GeometryAttribute::TEX_COORD, 12);
      encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, 10);
      draco::EncoderBuffer out;
      const draco::Status status = encoder.EncodeMeshToBuffer(dm, &out);
      EXPECT_TRUE(status.ok()) << status.error_msg_string();
      const std::vector<unsigned char> bytes(out.data(), out.data() + out.size());
      tinygltf::Value::Object ext;
      ext["bufferView"] = tinygltf::Value(AddView(&m, bytes));
      ext["attributes"] = tinygltf::Value(ids);
      prim.extensions["KHR_draco_mesh_compression"] = tinygltf::Value(ext);
    }
  }
  m.extensionsUsed.push_back("KHR_draco_mesh_compression");
  if (required) m.extensionsRequired.push_back("KHR_draco_mesh_compression");
  return m;
}

// Loads a glTF file with tinygltf as it is (no Draco decoding).
inline tinygltf::Model ReadPlain(const std::string& path) {
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  const bool ok = path.substr(path.size() - 4) == ".glb"
                      ? loader.LoadBinaryFromFile(&m, &err, &warn, path)
                      : loader.LoadASCIIFromFile(&m, &err, &warn, path);
  EXPECT_TRUE(ok) << path << ": " << err;
  return m;
}

}  // namespace banmo::synth::testing
