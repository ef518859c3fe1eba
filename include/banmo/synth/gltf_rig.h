// glTF 2.0 (.glb / .gltf) to Rig, with tinygltf.
//
// Supported: the node hierarchy of the default scene (TRS or matrix nodes),
// skins with inverse bind matrices (JOINTS_0/WEIGHTS_0 and JOINTS_1/WEIGHTS_1,
// so up to 8 joints per vertex), meshes without skin (rigidly attached to
// their node), several meshes and primitives (TRIANGLES, TRIANGLE_STRIP,
// TRIANGLE_FAN; points and lines are skipped), morph targets (POSITION
// deltas, driven by node/mesh weights and "weights" channels), materials'
// baseColorFactor and baseColorTexture (any TEXCOORD_n), COLOR_0 vertex
// colours (linear, converted to display values with gamma 1/2.2), and
// animation channels with LINEAR, STEP and CUBICSPLINE samplers; one skin
// per mesh. Files as exporters write them: .gltf with external .bin / image
// files or data URIs, KHR_draco_mesh_compression (libdraco),
// KHR_mesh_quantization, KHR_texture_transform (base colour texture),
// accessors without a bufferView (zeros) and sparse accessors. Extensions
// that change neither geometry nor base colour are ignored with a note; an
// `extensionsRequired` entry the loader cannot honour is an error naming the
// extension and the file (docs/synth.md lists them).
//
// The rest mesh is the bind pose: skinned primitives keep their stored
// positions (glTF ignores the mesh node's transform for skinned meshes);
// unskinned primitives are moved by their node's rest global transform.
#pragma once

#include <string>

#include "banmo/synth/rig.h"

namespace banmo::synth {

// Loads `path`. Throws InputError naming the file and the problem (missing
// or unparsable file, an unsupported required extension, a Draco stream that
// does not decode, no triangles, bad accessors).
Rig LoadGltfRig(const std::string& path);

}  // namespace banmo::synth
