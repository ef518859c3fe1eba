// glTF rigs (synth/gltf_*.cc, Draco included): the first byte selects .glb
// or .gltf; the rest is the file (external URIs resolve in the work folder).
#include "banmo/synth/gltf_rig.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string name = data[0] % 2 == 0 ? "rig.glb" : "rig.gltf";
  const std::string path = banmo::fuzz::WriteInput(name, banmo::fuzz::AsString(data + 1, size - 1));
  banmo::fuzz::Expect([&] { banmo::synth::LoadGltfRig(path); });
  return 0;
}
