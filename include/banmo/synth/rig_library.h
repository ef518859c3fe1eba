// Finding a rig by name: the built-in procedural creatures (compiled in from
// data/rigs/*.yaml) or a file path (.glb / .gltf, or a procedural .yaml).
#pragma once

#include <string>
#include <vector>

#include "banmo/synth/rig.h"

namespace banmo::synth {

// Names of the built-in rigs, sorted ("bird", "hand", "quadruped").
std::vector<std::string> BuiltinRigNames();

// YAML text of built-in rig `name`; throws InputError if there is none.
const std::string& BuiltinRigYaml(const std::string& name);

// `spec` is a built-in name or a path to a .glb, .gltf or .yaml file.
// Throws InputError naming the spec when it is neither, or when the file is bad.
Rig LoadRig(const std::string& spec);

}  // namespace banmo::synth
