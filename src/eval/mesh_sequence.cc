#include "banmo/eval/mesh_sequence.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "banmo/geometry/mesh_io.h"
#include "banmo/util/error.h"
#include "banmo/util/parallel.h"

namespace banmo {
namespace {

bool IsMeshFile(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".ply" || ext == ".obj";
}

}  // namespace

std::vector<std::string> ListMeshFiles(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) {
    ThrowInputError(path, ": does not exist (expected a .ply/.obj file or a folder of them)");
  }
  if (fs::is_regular_file(status)) {
    if (!IsMeshFile(path)) ThrowInputError(path, ": not a mesh file (expected .ply or .obj)");
    return {path};
  }
  if (!fs::is_directory(status)) {
    ThrowInputError(path, ": not a file or folder (expected a .ply/.obj file or a folder of them)");
  }
  std::vector<std::string> files;
  for (fs::directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->is_regular_file(ec) && IsMeshFile(it->path())) files.push_back(it->path().string());
  }
  if (ec) ThrowInputError(path, ": cannot list folder: ", ec.message());
  if (files.empty()) ThrowInputError(path, ": folder holds no .ply or .obj mesh");
  std::sort(files.begin(), files.end(), [](const std::string& a, const std::string& b) {
    return fs::path(a).filename().string() < fs::path(b).filename().string();
  });
  return files;
}

std::vector<TriangleMesh> ReadMeshes(const std::vector<std::string>& files) {
  std::vector<TriangleMesh> meshes(files.size());
  ParallelFor(static_cast<int>(files.size()), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      meshes[static_cast<std::size_t>(i)] = ReadMesh(files[static_cast<std::size_t>(i)]);
    }
  });
  return meshes;
}

}  // namespace banmo
