#include "gltf_document.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <utility>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo::synth::internal {
namespace {

using Json = nlohmann::json;

// Extensions that change neither the geometry nor the base colour the
// rasteriser uses: safe to ignore, even when a file requires them.
const std::set<std::string>& IgnorableExtensions() {
  static const std::set<std::string> names = {
      "KHR_materials_anisotropy",
      "KHR_materials_clearcoat",
      "KHR_materials_dispersion",
      "KHR_materials_emissive_strength",
      "KHR_materials_ior",
      "KHR_materials_iridescence",
      "KHR_materials_sheen",
      "KHR_materials_specular",
      "KHR_materials_transmission",
      "KHR_materials_unlit",
      "KHR_materials_variants",
      "KHR_materials_volume",
      "KHR_lights_punctual",
      "KHR_xmp_json_ld",
      "KHR_xmp",
  };
  return names;
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInputError(path, ": cannot open the glTF file");
  return std::string(std::istreambuf_iterator<char>(in), {});
}

uint32_t ReadU32(const std::string& bytes, std::size_t offset) {
  uint32_t v;
  std::memcpy(&v, bytes.data() + offset, 4);
  return v;
}

void AppendU32(std::string* bytes, uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);
  bytes->append(b, 4);
}

constexpr uint32_t kGlbMagic = 0x46546C67;   // "glTF"
constexpr uint32_t kJsonChunk = 0x4E4F534A;  // "JSON"

// The JSON chunk of a .glb (version 2), and where it ends.
std::string GlbJson(const std::string& path, const std::string& bytes, std::size_t* json_end) {
  if (bytes.size() < 20 || ReadU32(bytes, 0) != kGlbMagic) {
    ThrowInputError(path, ": cannot read glTF: not a binary glTF file (no 'glTF' magic)");
  }
  if (ReadU32(bytes, 4) != 2) {
    ThrowInputError(path, ": cannot read glTF: binary glTF version ", ReadU32(bytes, 4),
                    ", expected 2");
  }
  const uint32_t length = ReadU32(bytes, 12);
  if (ReadU32(bytes, 16) != kJsonChunk || 20 + std::size_t{length} > bytes.size()) {
    ThrowInputError(path, ": cannot read glTF: the first chunk is not a complete JSON chunk");
  }
  *json_end = 20 + length;
  return bytes.substr(20, length);
}

// The .glb with its JSON chunk replaced by `json` (padded with spaces).
std::string ReplaceGlbJson(const std::string& bytes, std::size_t json_end, std::string json) {
  while (json.size() % 4 != 0) json.push_back(' ');
  std::string out = bytes.substr(0, 8);
  const std::string rest = bytes.substr(json_end);
  AppendU32(&out, static_cast<uint32_t>(12 + 8 + json.size() + rest.size()));
  AppendU32(&out, static_cast<uint32_t>(json.size()));
  AppendU32(&out, kJsonChunk);
  out += json;
  out += rest;
  return out;
}

void CheckExtensions(const std::string& path, const Json& doc) {
  const std::vector<std::string>& supported = SupportedGltfExtensions();
  const auto required = doc.find("extensionsRequired");
  if (required != doc.end() && required->is_array()) {
    for (const Json& e : *required) {
      const std::string name = e.is_string() ? e.get<std::string>() : e.dump();
      if (std::find(supported.begin(), supported.end(), name) == supported.end()) {
        std::string list;
        for (const std::string& s : supported) list += (list.empty() ? "" : ", ") + s;
        ThrowInputError(
            path, ": the file requires the glTF extension '", name,
            "' (extensionsRequired), which this loader does not support (supported: ", list, ")");
      }
    }
  }
  const auto used = doc.find("extensionsUsed");
  if (used != doc.end() && used->is_array()) {
    for (const Json& e : *used) {
      if (!e.is_string()) continue;
      const std::string name = e.get<std::string>();
      if (IgnorableExtensions().count(name)) {
        LOG(INFO) << path << ": note: ignoring " << name
                  << " (it changes neither geometry nor base colour)";
      } else if (std::find(supported.begin(), supported.end(), name) == supported.end()) {
        LOG(INFO) << path << ": note: ignoring the optional extension " << name;
      }
    }
  }
}

// Removes `indices` from Draco-compressed primitives (their accessor has no
// bufferView, which tinygltf refuses); returns (mesh, primitive) -> accessor.
std::map<std::pair<int, int>, int> HideDracoIndices(Json* doc) {
  std::map<std::pair<int, int>, int> hidden;
  const auto meshes = doc->find("meshes");
  if (meshes == doc->end() || !meshes->is_array()) return hidden;
  for (std::size_t m = 0; m < meshes->size(); ++m) {
    Json& mesh = (*meshes)[m];
    if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) {
      continue;
    }
    Json& prims = mesh["primitives"];
    for (std::size_t p = 0; p < prims.size(); ++p) {
      Json& prim = prims[p];
      if (!prim.is_object() || !prim.contains("extensions") || !prim["extensions"].is_object() ||
          !prim["extensions"].contains(kDracoExtension) || !prim.contains("indices") ||
          !prim["indices"].is_number_integer()) {
        continue;
      }
      hidden[{static_cast<int>(m), static_cast<int>(p)}] = prim["indices"].get<int>();
      prim.erase("indices");
    }
  }
  return hidden;
}

}  // namespace

const std::vector<std::string>& SupportedGltfExtensions() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out = {kDracoExtension, kQuantizationExtension,
                                    kTextureTransformExtension};
    out.insert(out.end(), IgnorableExtensions().begin(), IgnorableExtensions().end());
    return out;
  }();
  return names;
}

tinygltf::Model ReadGltfDocument(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) ThrowInputError(path, ": no such glTF file");
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext != ".glb" && ext != ".gltf") ThrowInputError(path, ": expected a .glb or .gltf file");
  const bool binary = ext == ".glb";
  std::string bytes = ReadBytes(path);
  std::size_t json_end = 0;
  const std::string text = binary ? GlbJson(path, bytes, &json_end) : bytes;
  Json doc = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    ThrowInputError(path, ": cannot read glTF: the JSON part is not a valid JSON object");
  }
  CheckExtensions(path, doc);
  const std::map<std::pair<int, int>, int> hidden = HideDracoIndices(&doc);
  if (!hidden.empty()) bytes = binary ? ReplaceGlbJson(bytes, json_end, doc.dump()) : doc.dump();

  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  std::string base_dir = std::filesystem::absolute(path).parent_path().string();
  bool ok = false;
  if (binary) {
    ok = loader.LoadBinaryFromMemory(&model, &err, &warn,
                                     reinterpret_cast<const unsigned char*>(bytes.data()),
                                     static_cast<unsigned int>(bytes.size()), base_dir);
  } else {
    ok = loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(),
                                    static_cast<unsigned int>(bytes.size()), base_dir);
  }
  if (!ok) ThrowInputError(path, ": cannot read glTF: ", err.empty() ? "unknown error" : err);
  if (!warn.empty()) LOG(WARNING) << path << ": " << warn;
  for (const auto& [where, accessor] : hidden) {
    model.meshes[where.first].primitives[where.second].indices = accessor;
  }
  return model;
}

}  // namespace banmo::synth::internal
