// Mesh sequences on disk: a folder with one .ply/.obj per frame, or one file.
#pragma once

#include <string>
#include <vector>

#include "banmo/geometry/mesh.h"

namespace banmo {

// A mesh file (.ply/.obj, any case) -> {path}; a folder -> its .ply/.obj
// files sorted by file name (byte order; zero-pad frame numbers). Throws
// InputError naming `path` if it does not exist, has another extension, or is
// a folder without meshes.
std::vector<std::string> ListMeshFiles(const std::string& path);

// ReadMesh (geometry/mesh_io.h) on every file, in parallel; the meshes in the
// files' order. A file's error is thrown once the other reads have finished.
std::vector<TriangleMesh> ReadMeshes(const std::vector<std::string>& files);

}  // namespace banmo
