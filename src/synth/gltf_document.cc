#include "gltf_document.h"

#include <algorithm>
#include <cctype>
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
#include "banmo/util/input_file.h"
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

// A .glb is parsed from memory with a 32-bit length; 1 GiB is far above any
// model the rasteriser can use.
constexpr std::uint64_t kMaxGltfBytes = std::uint64_t{1} << 30;

std::string ReadBytes(const std::string& path) {
  return ReadRegularFile(path, kMaxGltfBytes, " (the glTF file)");
}

// ---- External files: only inside the glTF's own folder. ----

// tinygltf's URI decoding, exactly (dlib::urldecode in tiny_gltf.h): '+' is a
// space, '%' and the next two characters are one byte (a character that is
// not a hex digit counts as 0), so the checks see the path tinygltf opens.
std::string UrlDecode(const std::string& s) {
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return 0;
  };
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '+') {
      out += ' ';
    } else if (s[i] == '%' && s.size() > i + 2) {
      out += static_cast<char>((hex(s[i + 1]) << 4) | hex(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

bool IsDataUri(const std::string& uri) { return uri.rfind("data:", 0) == 0; }

// True if `p` (made canonical) is `folder` or below it.
bool IsInside(const std::filesystem::path& p, const std::filesystem::path& folder) {
  auto f = folder.begin();
  auto q = p.begin();
  for (; f != folder.end(); ++f, ++q) {
    if (q == p.end() || *q != *f) return false;
  }
  return true;
}

// Why the decoded URI `uri` may not be opened from `folder`, or "".
std::string UriProblem(const std::string& uri, const std::filesystem::path& folder) {
  namespace fs = std::filesystem;
  if (uri.empty() || uri == ".") return "it names no file";
  if (uri.find('\0') != std::string::npos) return "it contains a NUL character";
  if (uri[0] == '/' || uri[0] == '\\') return "absolute paths are not allowed";
  const std::size_t colon = uri.find(':');
  if (colon != std::string::npos && uri.find('/') > colon) {
    return "URI schemes (file:, http:, ...) are not allowed; only relative file names and data: "
           "URIs";
  }
  for (const fs::path& part : fs::path(uri)) {
    if (part == "..") return "'..' may not leave the glTF's folder";
  }
  std::error_code ec;
  const fs::path resolved = fs::weakly_canonical(folder / uri, ec);
  if (ec) return "it cannot be resolved (" + ec.message() + ")";
  if (!IsInside(resolved, folder)) return "it resolves outside the glTF's folder (symbolic link)";
  if (fs::exists(resolved, ec) && !fs::is_regular_file(resolved, ec)) {
    return "it is not a regular file (a folder, FIFO or device)";
  }
  return "";
}

// Refuses buffer and image URIs that would open anything but a regular file
// inside `folder` (the canonical folder of the glTF file).
void CheckUris(const std::string& path, const Json& doc, const std::filesystem::path& folder) {
  for (const char* list : {"buffers", "images"}) {
    const auto it = doc.find(list);
    if (it == doc.end() || !it->is_array()) continue;
    for (std::size_t i = 0; i < it->size(); ++i) {
      const Json& entry = (*it)[i];
      if (!entry.is_object() || !entry.contains("uri")) continue;
      if (!entry["uri"].is_string())
        ThrowInputError(path, ": ", list, "[", i, "].uri: expected a string");
      const std::string uri = entry["uri"].get<std::string>();
      if (IsDataUri(uri)) continue;
      const std::string problem = UriProblem(UrlDecode(uri), folder);
      if (!problem.empty()) {
        ThrowInputError(path, ": ", list, "[", i, "].uri '", uri, "': ", problem,
                        " (a glTF may refer only to files inside its own folder)");
      }
    }
  }
}

// tinygltf file system callbacks that open only regular files inside the
// folder given as user data (tinygltf also searches the working directory).
bool FileExistsInside(const std::string& abs_filename, void* user_data) {
  const auto& folder = *static_cast<const std::filesystem::path*>(user_data);
  std::error_code ec;
  const std::filesystem::path p = std::filesystem::weakly_canonical(abs_filename, ec);
  return !ec && IsInside(p, folder) && std::filesystem::is_regular_file(p, ec);
}

std::string ExpandNothing(const std::string& path, void*) { return path; }

bool ReadWholeFileInside(std::vector<unsigned char>* out, std::string* err,
                         const std::string& filepath, void* user_data) {
  if (!FileExistsInside(filepath, user_data)) {
    if (err) *err += filepath + ": not a regular file inside the glTF's folder";
    return false;
  }
  try {
    const std::string bytes = ReadRegularFile(filepath, kMaxGltfBytes);
    out->assign(bytes.begin(), bytes.end());
    return true;
  } catch (const InputError& e) {
    if (err) *err += e.what();
    return false;
  }
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
  std::error_code exists_error;
  if (!std::filesystem::exists(path, exists_error)) ThrowInputError(path, ": no such glTF file");
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
  std::error_code ec;
  const std::filesystem::path folder =
      std::filesystem::weakly_canonical(std::filesystem::absolute(path).parent_path(), ec);
  if (ec) ThrowInputError(path, ": cannot resolve the glTF's folder (", ec.message(), ")");
  CheckUris(path, doc, folder);
  const std::map<std::pair<int, int>, int> hidden = HideDracoIndices(&doc);
  if (!hidden.empty()) bytes = binary ? ReplaceGlbJson(bytes, json_end, doc.dump()) : doc.dump();

  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  tinygltf::FsCallbacks callbacks = {&FileExistsInside, &ExpandNothing, &ReadWholeFileInside,
                                     nullptr, const_cast<std::filesystem::path*>(&folder)};
  loader.SetFsCallbacks(callbacks);
  std::string err, warn;
  const std::string base_dir = folder.string();
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
