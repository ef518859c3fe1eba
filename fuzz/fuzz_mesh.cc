// PLY and OBJ meshes (geometry/mesh_io.cc): the first byte selects the
// extension; the rest is the file.
#include "banmo/geometry/mesh_io.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string name = data[0] % 2 == 0 ? "mesh.ply" : "mesh.obj";
  const std::string path = banmo::fuzz::WriteInput(name, banmo::fuzz::AsString(data + 1, size - 1));
  banmo::fuzz::Expect([&] { banmo::ReadMesh(path); });
  return 0;
}
