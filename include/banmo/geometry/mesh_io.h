// Mesh file input/output (PLY binary/ASCII and OBJ). Reading is done with
// CGAL's polygon-soup readers; writing uses atomic files (util/atomic_file.h).
// Bad input (missing or unreadable file, non-triangle faces that cannot be
// triangulated, NaN/Inf vertices, indices out of range) throws InputError
// naming the file.
#pragma once

#include <string>

#include "banmo/geometry/mesh.h"

namespace banmo {

// Reads a .ply or .obj file (by extension, case-insensitive). Polygons with
// more than three vertices are fan-triangulated. Vertex colours are read from
// PLY files when present.
TriangleMesh ReadMesh(const std::string& path);

// Writes a binary little-endian PLY with vertex colours when the mesh has them.
void WritePly(const std::string& path, const TriangleMesh& mesh);

// Writes a Wavefront OBJ (vertex colours as the common "v x y z r g b"
// extension when present).
void WriteObj(const std::string& path, const TriangleMesh& mesh);

// Dispatches on the extension (.ply or .obj).
void WriteMesh(const std::string& path, const TriangleMesh& mesh);

}  // namespace banmo
