// KHR_draco_mesh_compression (private to the synth module): decodes a
// primitive's Draco stream with Debian's libdraco and hands the attributes
// and indices to GltfAccessors, so the rest of the loader reads them like
// any other accessor.
#pragma once

#include <string>
#include <vector>

#include "gltf_accessors.h"

namespace banmo::synth::internal {

// If `prim` carries KHR_draco_mesh_compression, decodes it, registers the
// decoded values of its attribute and indices accessors with `accessors`,
// stores the decoded triangle corners in `indices` (also when the primitive
// has no indices accessor: Draco may reorder vertices) and returns true.
// Returns false for other primitives. Throws InputError naming the file,
// mesh and what failed.
bool DecodeDracoPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& prim,
                          const std::string& mesh_name, GltfAccessors* accessors,
                          std::vector<int>* indices);

}  // namespace banmo::synth::internal
