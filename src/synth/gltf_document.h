// Reading a glTF 2.0 file (.glb or .gltf) into a tinygltf::Model, with the
// checks tinygltf does not make (private to the synth module):
//  - every entry of `extensionsRequired` must be one the loader honours,
//    otherwise InputError naming the extension and the file;
//  - extensions that change neither geometry nor base colour (most
//    KHR_materials_*, KHR_lights_punctual, ...) are ignored with a note;
//  - primitives compressed with KHR_draco_mesh_compression keep their
//    `indices` accessor, which has no bufferView (tinygltf refuses such an
//    accessor, so it is hidden from tinygltf and put back after parsing).
#pragma once

// Debian's libtinygltf-dev ships tinygltf as a shared library (with stb_image
// and JSON parsing compiled in), so TINYGLTF_IMPLEMENTATION is not defined
// here: see /usr/share/doc/libtinygltf-dev/README.Debian.
#include <tiny_gltf.h>

#include <string>
#include <vector>

namespace banmo::synth::internal {

inline constexpr char kDracoExtension[] = "KHR_draco_mesh_compression";
inline constexpr char kQuantizationExtension[] = "KHR_mesh_quantization";
inline constexpr char kTextureTransformExtension[] = "KHR_texture_transform";

// Extensions the loader honours when they are required: the three above and
// those it may ignore because they change neither geometry nor base colour.
const std::vector<std::string>& SupportedGltfExtensions();

// Parses `path` (.glb or .gltf; external .bin and image files are read from
// its folder, data URIs decoded). Throws InputError naming the file.
tinygltf::Model ReadGltfDocument(const std::string& path);

}  // namespace banmo::synth::internal
