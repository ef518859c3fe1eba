// Mesh reading with CGAL's polygon-soup readers (the same readers that
// CGAL::IO::read_polygon_soup dispatches to; called directly so that PLY
// vertex colours can be collected), and plain atomic writers for PLY and OBJ.
// CGAL stays inside this file: it is heavy to compile.
#include "banmo/geometry/mesh_io.h"

#include <CGAL/IO/Color.h>
#include <CGAL/IO/OBJ.h>
#include <CGAL/IO/PLY.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;

std::string LowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// Builds the TriangleMesh from a polygon soup, validating everything.
TriangleMesh SoupToMesh(const std::string& path, const std::vector<Point>& points,
                        const std::vector<std::vector<std::size_t>>& polygons,
                        const std::vector<CGAL::IO::Color>& vertex_colors) {
  if (points.empty()) ThrowInputError(path, ": mesh has no vertices (expected a non-empty mesh)");
  TriangleMesh mesh;
  const std::size_t num_vertices = points.size();
  mesh.vertices.resize(3, static_cast<Eigen::Index>(num_vertices));
  for (std::size_t i = 0; i < num_vertices; ++i) {
    const Point& p = points[i];
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z())) {
      ThrowInputError(path, ": vertex ", i, " has a non-finite coordinate (", p.x(), ", ", p.y(),
                      ", ", p.z(), "); expected finite numbers");
    }
    mesh.vertices.col(static_cast<Eigen::Index>(i)) << p.x(), p.y(), p.z();
  }
  std::size_t num_triangles = 0;
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    const auto& polygon = polygons[f];
    if (polygon.size() < 3) {
      ThrowInputError(path, ": face ", f, " has ", polygon.size(),
                      " vertices; expected a polygon with at least 3");
    }
    for (const std::size_t index : polygon) {
      if (index >= num_vertices) {
        ThrowInputError(path, ": face ", f, " refers to vertex ", index, " but the mesh has only ",
                        num_vertices, " vertices");
      }
    }
    num_triangles += polygon.size() - 2;
  }
  // Fan triangulation (v0, vi, vi+1) keeps the polygon's orientation.
  mesh.faces.resize(3, static_cast<Eigen::Index>(num_triangles));
  Eigen::Index t = 0;
  for (const auto& polygon : polygons) {
    for (std::size_t i = 1; i + 1 < polygon.size(); ++i) {
      mesh.faces.col(t++) << static_cast<int>(polygon[0]), static_cast<int>(polygon[i]),
          static_cast<int>(polygon[i + 1]);
    }
  }
  if (vertex_colors.size() == num_vertices) {
    mesh.colors.resize(3, static_cast<Eigen::Index>(num_vertices));
    for (std::size_t i = 0; i < num_vertices; ++i) {
      const CGAL::IO::Color& c = vertex_colors[i];
      mesh.colors.col(static_cast<Eigen::Index>(i)) << c.red(), c.green(), c.blue();
    }
  }
  return mesh;
}

void CheckWritable(const std::string& path, const TriangleMesh& mesh) {
  if (mesh.vertices.cols() == 0)
    ThrowInputError(path, ": refusing to write a mesh with no vertices");
  if (!mesh.vertices.allFinite()) ThrowInputError(path, ": refusing to write non-finite vertices");
  if (mesh.faces.cols() > 0 &&
      (mesh.faces.minCoeff() < 0 || mesh.faces.maxCoeff() >= mesh.NumVertices())) {
    ThrowInputError(path, ": refusing to write faces with vertex indices out of range");
  }
}

template <typename T>
void AppendRaw(std::string* out, const T& value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out->append(bytes, sizeof(T));
}

bool HostIsLittleEndian() {
  const std::uint16_t one = 1;
  unsigned char first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// Checks what CGAL's PLY reader assumes without checking: the vertex
// coordinates x, y, z are float or double properties (an integer one is a
// null pointer dereference in CGAL, an assertion in debug builds), every
// property line follows an element line (CGAL adds it to the last element
// of an empty list: undefined behaviour) and the header ends within 64 KiB.
// Both were found by fuzz/fuzz_mesh.cc. Lines are split as CGAL splits them.
void CheckPlyHeader(const std::string& path) {
  std::ifstream is(path, std::ios::binary);
  if (!is) ThrowInputError(path, ": cannot open mesh file for reading");
  std::string line, element;
  bool any_element = false;
  std::size_t read = 0;
  while (std::getline(is, line)) {
    read += line.size() + 1;
    if (read > 65536) ThrowInputError(path, ": PLY header longer than 64 KiB");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "end_header") return;
    if (keyword == "element") {
      words >> element;
      any_element = true;
    } else if (keyword == "property" && !any_element) {
      ThrowInputError(path, ": PLY header has a property before any element line");
    } else if (keyword == "property" && element == "vertex") {
      std::string type, name;
      words >> type >> name;
      if (type == "list") continue;
      const bool floating =
          type == "float" || type == "float32" || type == "double" || type == "float64";
      if ((name == "x" || name == "y" || name == "z") && !floating) {
        ThrowInputError(path, ": PLY vertex property '", name, "' has type '", type,
                        "', expected float or double");
      }
    }
  }
  ThrowInputError(path, ": could not parse the mesh (expected a valid .ply file; no end_header)");
}

}  // namespace

TriangleMesh ReadMesh(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    ThrowInputError(path, ": mesh file does not exist or is not a regular file");
  }
  const std::string ext = LowerExtension(path);
  std::vector<Point> points;
  std::vector<std::vector<std::size_t>> polygons;
  std::vector<CGAL::IO::Color> vertex_colors;
  bool ok = false;
  if (ext == ".ply") {
    CheckPlyHeader(path);
    std::ifstream is(path, std::ios::binary);
    if (!is) ThrowInputError(path, ": cannot open mesh file for reading");
    CGAL::IO::set_mode(is, CGAL::IO::BINARY);
    std::vector<CGAL::IO::Color> face_colors;  // read but unused
    ok = CGAL::IO::read_PLY(is, points, polygons, face_colors, vertex_colors, /*verbose=*/false);
  } else if (ext == ".obj") {
    std::ifstream is(path);
    if (!is) ThrowInputError(path, ": cannot open mesh file for reading");
    ok = CGAL::IO::read_OBJ(is, points, polygons, CGAL::parameters::verbose(false));
  } else {
    ThrowInputError(path, ": unsupported mesh extension '", ext, "' (expected .ply or .obj)");
  }
  if (!ok) ThrowInputError(path, ": could not parse the mesh (expected a valid ", ext, " file)");
  return SoupToMesh(path, points, polygons, vertex_colors);
}

void WritePly(const std::string& path, const TriangleMesh& mesh) {
  CheckWritable(path, mesh);
  CHECK(HostIsLittleEndian()) << "WritePly assumes a little-endian host";
  const bool colors = mesh.HasColors();
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\ncomment banmo-ceres\n"
         << "element vertex " << mesh.NumVertices() << "\n"
         << "property double x\nproperty double y\nproperty double z\n";
  if (colors) header << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header << "element face " << mesh.NumFaces() << "\n"
         << "property list uchar int vertex_indices\nend_header\n";
  std::string out = header.str();
  out.reserve(out.size() + static_cast<std::size_t>(mesh.NumVertices()) * 27 +
              static_cast<std::size_t>(mesh.NumFaces()) * 13);
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    for (int k = 0; k < 3; ++k) AppendRaw(&out, mesh.vertices(k, i));
    if (colors) {
      for (int k = 0; k < 3; ++k) AppendRaw(&out, mesh.colors(k, i));
    }
  }
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    AppendRaw(&out, static_cast<std::uint8_t>(3));
    for (int k = 0; k < 3; ++k) AppendRaw(&out, static_cast<std::int32_t>(mesh.faces(k, f)));
  }
  WriteFileAtomic(path, out);
}

void WriteObj(const std::string& path, const TriangleMesh& mesh) {
  CheckWritable(path, mesh);
  const bool colors = mesh.HasColors();
  std::string out = "# banmo-ceres\n";
  char line[256];
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    int n;
    if (colors) {
      n = std::snprintf(line, sizeof(line), "v %.17g %.17g %.17g %.6g %.6g %.6g\n",
                        mesh.vertices(0, i), mesh.vertices(1, i), mesh.vertices(2, i),
                        mesh.colors(0, i) / 255.0, mesh.colors(1, i) / 255.0,
                        mesh.colors(2, i) / 255.0);
    } else {
      n = std::snprintf(line, sizeof(line), "v %.17g %.17g %.17g\n", mesh.vertices(0, i),
                        mesh.vertices(1, i), mesh.vertices(2, i));
    }
    out.append(line, static_cast<std::size_t>(n));
  }
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const int n = std::snprintf(line, sizeof(line), "f %d %d %d\n", mesh.faces(0, f) + 1,
                                mesh.faces(1, f) + 1, mesh.faces(2, f) + 1);
    out.append(line, static_cast<std::size_t>(n));
  }
  WriteFileAtomic(path, out);
}

void WriteMesh(const std::string& path, const TriangleMesh& mesh) {
  const std::string ext = LowerExtension(path);
  if (ext == ".ply") {
    WritePly(path, mesh);
  } else if (ext == ".obj") {
    WriteObj(path, mesh);
  } else {
    ThrowInputError(path, ": unsupported mesh extension '", ext, "' (expected .ply or .obj)");
  }
}

}  // namespace banmo
