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
// animation channels with LINEAR, STEP and CUBICSPLINE samplers.
//
// The rest mesh is the bind pose: skinned primitives keep their stored
// positions (glTF ignores the mesh node's transform for skinned meshes);
// unskinned primitives are moved by their node's rest global transform.
#pragma once

#include <string>

#include "banmo/synth/rig.h"

namespace banmo::synth {

// Loads `path`. Throws InputError naming the file and the problem (missing
// or unparsable file, no triangles, bad accessors, unsupported features such
// as sparse accessors).
Rig LoadGltfRig(const std::string& path);

}  // namespace banmo::synth
