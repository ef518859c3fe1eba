// eval/mesh_sequence.h: listing and reading a mesh sequence.
#include "banmo/eval/mesh_sequence.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "banmo/geometry/mesh_io.h"
#include "banmo/util/error.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

TriangleMesh Tetrahedron(double size) {
  TriangleMesh mesh;
  mesh.vertices.resize(3, 4);
  mesh.vertices << 0, size, 0, 0, 0, 0, size, 0, 0, 0, 0, size;
  mesh.faces.resize(3, 4);
  mesh.faces << 0, 0, 0, 1, 2, 1, 3, 2, 1, 3, 2, 3;
  return mesh;
}

class MeshSequenceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("banmo_mesh_sequence_test_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

TEST_F(MeshSequenceTest, AFolderListsItsMeshesByFileName) {
  WriteMesh(Path("0010.ply"), Tetrahedron(3));
  WriteMesh(Path("0002.ply"), Tetrahedron(2));
  WriteMesh(Path("0001.obj"), Tetrahedron(1));
  std::ofstream(Path("notes.txt")) << "not a mesh\n";
  fs::create_directories(dir_ / "sub.ply");  // a folder, not a mesh
  const std::vector<std::string> files = ListMeshFiles(dir_.string());
  ASSERT_EQ(files.size(), 3u);
  EXPECT_EQ(fs::path(files[0]).filename(), "0001.obj");
  EXPECT_EQ(fs::path(files[1]).filename(), "0002.ply");
  EXPECT_EQ(fs::path(files[2]).filename(), "0010.ply");
  // ReadMeshes keeps the order.
  const std::vector<TriangleMesh> meshes = ReadMeshes(files);
  ASSERT_EQ(meshes.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(meshes[i].NumVertices(), 4);
    EXPECT_EQ(meshes[i].NumFaces(), 4);
    EXPECT_NEAR(meshes[i].vertices.maxCoeff(), i + 1.0, 1e-6);
  }
}

TEST_F(MeshSequenceTest, OneFileIsASequenceOfOne) {
  WriteMesh(Path("frame.PLY"), Tetrahedron(1));
  EXPECT_EQ(ListMeshFiles(Path("frame.PLY")), std::vector<std::string>{Path("frame.PLY")});
}

TEST_F(MeshSequenceTest, ErrorsNameThePath) {
  auto error_of = [](const std::string& path) -> std::string {
    try {
      ListMeshFiles(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error_of(Path("missing")).find("missing: does not exist"), std::string::npos);
  std::ofstream(Path("notes.txt")) << "x\n";
  EXPECT_NE(error_of(Path("notes.txt")).find("notes.txt: not a mesh file"), std::string::npos);
  fs::create_directories(dir_ / "empty");
  EXPECT_NE(error_of(Path("empty")).find("holds no .ply or .obj"), std::string::npos);
  // ReadMeshes on a damaged file names it.
  std::ofstream(Path("bad.ply")) << "ply\nformat nonsense\n";
  EXPECT_THROW(ReadMeshes({Path("bad.ply")}), InputError);
}

}  // namespace
}  // namespace banmo
