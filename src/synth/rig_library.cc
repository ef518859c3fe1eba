#include "banmo/synth/rig_library.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "banmo/synth/gltf_rig.h"
#include "banmo/synth/procedural_rig.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"

namespace banmo::synth {
namespace internal {
// Defined in the generated builtin_rigs.cc (see src/synth/CMakeLists.txt).
const std::map<std::string, std::string>& BuiltinRigYaml();
}  // namespace internal

std::vector<std::string> BuiltinRigNames() {
  std::vector<std::string> names;
  for (const auto& [name, text] : internal::BuiltinRigYaml()) names.push_back(name);
  return names;  // std::map keeps them sorted
}

const std::string& BuiltinRigYaml(const std::string& name) {
  const auto& rigs = internal::BuiltinRigYaml();
  auto it = rigs.find(name);
  if (it == rigs.end()) {
    std::ostringstream os;
    for (const auto& n : BuiltinRigNames()) os << (os.tellp() > 0 ? ", " : "") << n;
    ThrowInputError("unknown rig '", name, "': expected one of ", os.str(),
                    " or a path to a .glb/.gltf/.yaml file");
  }
  return it->second;
}

Rig LoadRig(const std::string& spec) {
  const auto& rigs = internal::BuiltinRigYaml();
  if (rigs.count(spec)) return BuildProceduralRig(rigs.at(spec), "builtin rig '" + spec + "'");
  std::string ext = std::filesystem::path(spec).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext == ".glb" || ext == ".gltf") return LoadGltfRig(spec);
  if (ext == ".yaml" || ext == ".yml") {
    return BuildProceduralRig(ReadRegularFile(spec, kMaxTextFileBytes, " (the rig file)"), spec);
  }
  BuiltinRigYaml(spec);  // throws the "unknown rig" error listing the names
  ThrowInputError("unknown rig '", spec, "'");
}

}  // namespace banmo::synth
