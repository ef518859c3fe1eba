#include "banmo/geometry/mesh_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "banmo/util/error.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

class MeshIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("banmo_mesh_io_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  std::string WriteText(const std::string& name, const std::string& text) const {
    std::ofstream(Path(name), std::ios::binary) << text;
    return Path(name);
  }
  // The InputError message of ReadMesh(path), or "" if it does not throw.
  static std::string ReadError(const std::string& path) {
    try {
      ReadMesh(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

TriangleMesh Tetrahedron(bool colors) {
  TriangleMesh mesh;
  mesh.vertices.resize(3, 4);
  mesh.vertices << 0.1, 1.0 / 3.0, 0, 0,  //
      0, 1, -2.5e-7, 0,                   //
      3, 0, 1, 1e6;
  mesh.faces.resize(3, 4);
  mesh.faces << 0, 0, 0, 1,  //
      2, 1, 3, 2,            //
      1, 3, 2, 3;
  if (colors) {
    mesh.colors.resize(3, 4);
    mesh.colors << 255, 0, 10, 200,  //
        0, 255, 20, 100,             //
        7, 0, 30, 0;
  }
  return mesh;
}

TEST_F(MeshIo, PlyRoundTripIsExactWithColours) {
  const TriangleMesh mesh = Tetrahedron(true);
  WritePly(Path("t.ply"), mesh);
  const TriangleMesh back = ReadMesh(Path("t.ply"));
  EXPECT_EQ(back.vertices, mesh.vertices);  // binary doubles: bit exact
  EXPECT_EQ(back.faces, mesh.faces);
  ASSERT_TRUE(back.HasColors());
  EXPECT_EQ(back.colors, mesh.colors);
}

TEST_F(MeshIo, ObjRoundTripAndExtensionDispatch) {
  const TriangleMesh mesh = Tetrahedron(false);
  WriteMesh(Path("t.OBJ"), mesh);
  const TriangleMesh back = ReadMesh(Path("t.OBJ"));
  EXPECT_EQ(back.vertices, mesh.vertices);  // %.17g round-trips doubles exactly
  EXPECT_EQ(back.faces, mesh.faces);
  EXPECT_FALSE(back.HasColors());
  EXPECT_THROW(WriteMesh(Path("t.stl"), mesh), InputError);
}

// Found by fuzz/fuzz_mesh.cc: an integer vertex coordinate made CGAL's PLY
// reader dereference a null pointer (an assertion in debug builds).
TEST_F(MeshIo, IntegerCoordinatesOrphanPropertiesAndUnendedHeadersAreRefused) {
  const std::string path =
      WriteText("int.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\n"
                "property float x\nproperty float y\nproperty uint32 z\n"
                "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(ReadError(path),
            path + ": PLY vertex property 'z' has type 'uint32', expected float or double");
  // Found by the 10-minute run: a property line before any element line
  // (here "element" misspelt) was added by CGAL to the last element of an
  // empty list (undefined behaviour, UBSan).
  const std::string orphan =
      WriteText("orphan.ply",
                "ply\nformat ascii 1.0\nelement$ vertex 3\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n");
  EXPECT_EQ(ReadError(orphan), orphan + ": PLY header has a property before any element line");
  const std::string open = WriteText("open.ply", "ply\nformat ascii 1.0\nelement vertex 3\n");
  EXPECT_EQ(ReadError(open), open +
                                 ": could not parse the mesh (expected a valid .ply file; no "
                                 "end_header)");
}

TEST_F(MeshIo, AsciiPlyWithColoursAndQuadIsFanTriangulated) {
  const std::string path =
      WriteText("quad.ply",
                "ply\nformat ascii 1.0\nelement vertex 5\n"
                "property float x\nproperty float y\nproperty float z\n"
                "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                "element face 2\nproperty list uchar int vertex_indices\n"
                "end_header\n"
                "0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 1 2 3\n"
                "0.5 0.5 1 4 5 6\n"
                "4 0 1 2 3\n3 0 1 4\n");
  const TriangleMesh mesh = ReadMesh(path);
  ASSERT_EQ(mesh.NumVertices(), 5);
  ASSERT_EQ(mesh.NumFaces(), 3);
  Eigen::Matrix3Xi expected(3, 3);
  expected << 0, 0, 0,  //
      1, 2, 1,          //
      2, 3, 4;
  EXPECT_EQ(mesh.faces, expected);
  ASSERT_TRUE(mesh.HasColors());
  EXPECT_EQ(mesh.colors(2, 2), 255);
  EXPECT_EQ(mesh.colors(0, 4), 4);
}

TEST_F(MeshIo, ObjPolygonIsFanTriangulated) {
  const std::string path =
      WriteText("pent.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 1.5 0\nv 0 1 0\nf 1 2 3 4 5\n");
  const TriangleMesh mesh = ReadMesh(path);
  EXPECT_EQ(mesh.NumFaces(), 3);
  EXPECT_EQ(mesh.faces.col(2), Eigen::Vector3i(0, 3, 4));
}

TEST_F(MeshIo, ErrorsNameTheFile) {
  EXPECT_NE(ReadError(Path("missing.ply")).find("missing.ply: mesh file does not exist"),
            std::string::npos);
  EXPECT_NE(ReadError(WriteText("m.stl", "solid")).find("unsupported mesh extension"),
            std::string::npos);
  const std::string garbage = WriteText("garbage.ply", "not a ply at all\n");
  EXPECT_NE(ReadError(garbage).find(garbage + ": could not parse"), std::string::npos);
  const std::string empty = WriteText(
      "empty.ply",
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
      "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n");
  EXPECT_NE(ReadError(empty).find(empty + ": mesh has no vertices"), std::string::npos);
  const std::string out_of_range = WriteText("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  const std::string message = ReadError(out_of_range);
  EXPECT_NE(message.find(out_of_range), std::string::npos) << message;
  const std::string degenerate =
      WriteText("line.ply",
                "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                "end_header\n0 0 0\n1 0 0\n2 0 1\n");
  EXPECT_NE(ReadError(degenerate).find("expected a polygon with at least 3"), std::string::npos);
}

TEST_F(MeshIo, NonFiniteVertexIsAnError) {
  // Binary PLY with a NaN (ASCII "nan" is already a parse error).
  TriangleMesh mesh = Tetrahedron(false);
  WritePly(Path("ok.ply"), mesh);
  std::string bytes;
  {
    std::ifstream in(Path("ok.ply"), std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::size_t body = bytes.find("end_header\n") + 11;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  bytes.replace(body + 3 * sizeof(double) * 2 + sizeof(double), sizeof(double),
                reinterpret_cast<const char*>(&nan), sizeof(double));  // vertex 2, y
  const std::string path = WriteText("nan.ply", bytes);
  EXPECT_NE(ReadError(path).find(path + ": vertex 2 has a non-finite coordinate"),
            std::string::npos)
      << ReadError(path);
  mesh.vertices(0, 1) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(WritePly(Path("inf.ply"), mesh), InputError);
  EXPECT_FALSE(fs::exists(Path("inf.ply")));
}

}  // namespace
}  // namespace banmo
