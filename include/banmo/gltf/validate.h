// A glTF 2.0 validator-style check of a loaded document (tinygltf::Model),
// run by the exporter on its own output before anything is written and
// usable on any loaded file (docs/export.md). It covers the subset of the
// Khronos glTF-Validator's checks that matter for skinned, animated meshes:
//   - every index (scene, node, mesh, accessor, buffer view, buffer, skin,
//     sampler) in range; accessors and buffer views inside their buffers,
//     strides >= element size; no node cycles or nodes with two parents;
//   - POSITION: float VEC3, min/max present and equal (in float) to the data's
//     bounds; all float attribute data finite; NORMAL unit length;
//   - indices: unsigned integer, < vertex count, count a multiple of 3 for
//     TRIANGLES; all attributes of a primitive have the same count;
//   - JOINTS_0: unsigned byte/short VEC4, every index < the skin's joint
//     count; WEIGHTS_0: float (or normalised unsigned byte/short) VEC4,
//     non-negative, sum 1 within weight_sum_tolerance; a primitive with
//     joints is on a node with a skin;
//   - skins: joints are valid nodes, inverseBindMatrices has one MAT4 per
//     joint, each finite and affine (last row 0 0 0 1);
//   - animations: channel targets valid; sampler input float scalar with
//     min/max present, times >= 0 and strictly increasing; output count =
//     input count (x3 for CUBICSPLINE); rotation outputs unit quaternions
//     within unit_tolerance; translation/scale outputs finite.
#pragma once

#include <string>
#include <vector>

namespace tinygltf {
class Model;
}

namespace banmo {

struct GltfValidationOptions {
  // |sum of a vertex's weights - 1| allowed (> 0). Default 2e-6: float32
  // weights renormalised in double and rounded carry about 1e-7 per weight
  // (the exporter's are within 2.4e-7); a normalised-uint8 file needs about
  // 4 / 255 / 2.
  double weight_sum_tolerance = 2e-6;
  // | |v| - 1 | allowed for rotations and normals (> 0): float32 rounding of
  // a unit vector gives about 1e-7; 1e-5 leaves room for files written by
  // other tools.
  double unit_tolerance = 1e-5;
  // Stop after this many problems (>= 1).
  int max_problems = 20;

  // Throws InputError naming the field on a violated constraint.
  void Check() const;
};

// Problems found in `gltf`, each a one-line message naming the object
// ("meshes[0].primitives[0] WEIGHTS_0 vertex 17: weights sum to 0.98");
// empty if the document passes.
std::vector<std::string> ValidateGltf(const tinygltf::Model& gltf,
                                      const GltfValidationOptions& options = {});

// Throws InputError "<what>: invalid glTF: <first problems>" if
// ValidateGltf finds anything.
void CheckGltfOrThrow(const tinygltf::Model& gltf, const std::string& what,
                      const GltfValidationOptions& options = {});

}  // namespace banmo
