// glTF files as users have them: Draco compression, quantised attributes,
// texture transforms, sparse and bufferless accessors, one skin per mesh,
// .gltf with external files or data URIs, required extensions. Every file is
// made at test time (gltf_files.h); nothing here is committed.
#include "banmo/synth/gltf_rig.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "../common/shared_assets.h"
#include "banmo/util/error.h"
#include "gltf_files.h"

namespace banmo::synth {
namespace {

using testing::AddAccessor;
using testing::TinyStrip;
using testing::WriteGltf;

const std::string kFox = banmo::testing::SharedAsset("data/gltf/Fox/Fox.glb");

std::string Temp(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/gltf_rig_test";
  std::filesystem::create_directories(dir);
  return dir + "/" + name;
}

// Largest distance from a column of `a` to its nearest column of `b`.
double OneSidedDistance(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  double worst = 0;
  for (int i = 0; i < a.cols(); ++i) {
    worst = std::max(worst, (b.colwise() - a.col(i)).colwise().norm().minCoeff());
  }
  return worst;
}

double SymmetricDistance(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  return std::max(OneSidedDistance(a, b), OneSidedDistance(b, a));
}

// Number of faces of `a` with no face of `b` whose corners match its corners
// within `tolerance` (in any order): 0 when the triangles are the same.
int UnmatchedFaces(const Rig& a, const Rig& b, double tolerance) {
  int unmatched = 0;
  for (int f = 0; f < a.NumFaces(); ++f) {
    bool found = false;
    for (int g = 0; g < b.NumFaces() && !found; ++g) {
      double worst = 0;
      for (int i = 0; i < 3; ++i) {
        double best = 1e300;
        for (int j = 0; j < 3; ++j) {
          best = std::min(
              best,
              (a.rest_vertices.col(a.faces(i, f)) - b.rest_vertices.col(b.faces(j, g))).norm());
        }
        worst = std::max(worst, best);
      }
      found = worst < tolerance;
    }
    unmatched += found ? 0 : 1;
  }
  return unmatched;
}

std::string LoadError(const std::string& path) {
  try {
    LoadGltfRig(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(GltfDraco, FoxDecodesWithinTheQuantisationTolerance) {
  ASSERT_TRUE(banmo::testing::SharedAssetExists(kFox));
  const Rig original = LoadGltfRig(kFox);
  constexpr int kBits = 14;
  const std::string path = Temp("fox_draco.glb");
  WriteGltf(testing::DracoCompressed(testing::ReadPlain(kFox), kBits), path);
  const Rig draco = LoadGltfRig(path);
  EXPECT_EQ(draco.Validate(), "");
  EXPECT_EQ(draco.NumFaces(), original.NumFaces());
  EXPECT_EQ(draco.animations.size(), 3u);
  ASSERT_EQ(draco.textures.size(), 1u);
  // Draco quantises each axis to 2^14 - 1 steps over the bounding cube:
  // error <= half a step per axis, so <= sqrt(3) / 2 steps in 3D.
  const Eigen::Vector3d extent =
      original.rest_vertices.rowwise().maxCoeff() - original.rest_vertices.rowwise().minCoeff();
  const double step = extent.maxCoeff() / ((1 << kBits) - 1);
  const double tolerance = std::sqrt(3.0) / 2 * step * 1.01;
  // Draco may reorder vertices: compare as point sets, both ways.
  EXPECT_LT(SymmetricDistance(draco.rest_vertices, original.rest_vertices), tolerance);
  EXPECT_EQ(UnmatchedFaces(draco, original, tolerance), 0);
  EXPECT_EQ(UnmatchedFaces(original, draco, tolerance), 0);
  // Skinning survives (joints and weights are stored losslessly): posed
  // meshes agree to the same tolerance times the largest joint scale (1 here).
  const Animation& walk = original.animations[1];
  const double t = walk.StartTime() + 0.4 * walk.Duration();
  const Eigen::Matrix3Xd posed_original = PoseRig(original, &walk, t);
  const Eigen::Matrix3Xd posed_draco = PoseRig(draco, &draco.animations[1], t);
  EXPECT_LT(SymmetricDistance(posed_draco, posed_original), 2 * tolerance);
  EXPECT_GT((posed_original - original.rest_vertices).colwise().norm().maxCoeff(), 5.0);
}

// A file from another encoder: Debian's draco_transcoder (package `draco`,
// tools/install_deps.sh), which also quantises the skin weights.
TEST(GltfDraco, TranscoderFoxMatchesTheOriginal) {
  ASSERT_TRUE(banmo::testing::SharedAssetExists(kFox));
  const std::string path = Temp("fox_transcoded.glb");
  std::filesystem::remove(path);
  const std::string command = "draco_transcoder -i " + kFox + " -o " + path +
                              " -qp 14 -qt 12 -qw 12 > " + Temp("transcoder.log") + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0)
      << command << " failed (is Debian's `draco` package installed? tools/install_deps.sh)";
  {  // plain tinygltf refuses it (the reason for the JSON pre-pass)
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    EXPECT_NE(bytes.find("\"extensionsRequired\":[\"KHR_draco_mesh_compression\"]"),
              std::string::npos);
  }
  const Rig original = LoadGltfRig(kFox);
  const Rig draco = LoadGltfRig(path);
  EXPECT_EQ(draco.NumFaces(), original.NumFaces());
  ASSERT_EQ(draco.animations.size(), 3u);
  const Eigen::Vector3d extent =
      original.rest_vertices.rowwise().maxCoeff() - original.rest_vertices.rowwise().minCoeff();
  const double step = extent.maxCoeff() / ((1 << 14) - 1);
  EXPECT_LT(SymmetricDistance(draco.rest_vertices, original.rest_vertices),
            std::sqrt(3.0) / 2 * step * 1.01);
  EXPECT_EQ(UnmatchedFaces(draco, original, std::sqrt(3.0) / 2 * step * 1.01), 0);
  // Posed: 12-bit weights move a vertex by at most a few 1e-4 of the
  // extent here; 1e-3 of the extent leaves room without hiding a wrong
  // joint (those move vertices by tens of percent).
  const Animation& run = original.animations[2];
  const double t = run.StartTime() + 0.5 * run.Duration();
  EXPECT_LT(SymmetricDistance(PoseRig(draco, &draco.animations[2], t), PoseRig(original, &run, t)),
            1e-3 * extent.maxCoeff());
}

TEST(GltfDraco, TinyStripKeepsFacesUvsAndSkinning) {
  const std::string plain = Temp("strip.glb");
  const std::string draco = Temp("strip_draco.glb");
  WriteGltf(TinyStrip(), plain);
  WriteGltf(testing::DracoCompressed(TinyStrip(), 16, /*required=*/false), draco);
  const Rig a = LoadGltfRig(plain);
  const Rig b = LoadGltfRig(draco);
  ASSERT_EQ(b.NumFaces(), 4);
  const double tolerance = 2.0 / ((1 << 16) - 1);
  for (double t : {0.0, 0.5, 1.0}) {
    EXPECT_LT(SymmetricDistance(PoseRig(a, &a.animations[0], t), PoseRig(b, &b.animations[0], t)),
              tolerance)
        << t;
  }
  // Every decoded face is a face of the original and back (same corners).
  EXPECT_EQ(UnmatchedFaces(b, a, tolerance), 0);
  EXPECT_EQ(UnmatchedFaces(a, b, tolerance), 0);
  for (int v = 0; v < b.rest_vertices.cols(); ++v) {
    EXPECT_NEAR(b.uvs(0, v), b.rest_vertices(0, v), 1e-3);
    EXPECT_NEAR(b.uvs(1, v), b.rest_vertices(1, v) / 2, 1e-3);
  }
}

TEST(GltfDraco, CorruptStreamNamesTheExtension) {
  tinygltf::Model m = testing::DracoCompressed(TinyStrip(), 14);
  const int view = m.meshes[0]
                       .primitives[0]
                       .extensions["KHR_draco_mesh_compression"]
                       .Get("bufferView")
                       .GetNumberAsInt();
  auto& data = m.buffers[0].data;
  for (std::size_t i = 0; i < m.bufferViews[view].byteLength; ++i) {
    data[m.bufferViews[view].byteOffset + i] = static_cast<unsigned char>(i * 37);
  }
  const std::string path = Temp("strip_corrupt_draco.glb");
  WriteGltf(m, path);
  const std::string error = LoadError(path);
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find("KHR_draco_mesh_compression"), std::string::npos) << error;
}

TEST(GltfExtensions, UnknownRequiredExtensionIsRefusedByName) {
  tinygltf::Model m = TinyStrip();
  m.extensionsUsed = {"EXT_imaginary_compression"};
  m.extensionsRequired = {"EXT_imaginary_compression"};
  const std::string path = Temp("strip_unknown.glb");
  WriteGltf(m, path);
  const std::string error = LoadError(path);
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find("requires the glTF extension 'EXT_imaginary_compression'"),
            std::string::npos)
      << error;
  // Only used (not required): ignored, the file loads.
  m.extensionsRequired.clear();
  WriteGltf(m, path);
  EXPECT_EQ(LoadGltfRig(path).NumFaces(), 4);
}

TEST(GltfExtensions, MaterialExtensionsAreIgnored) {
  tinygltf::Model m = TinyStrip();
  m.extensionsUsed = {"KHR_materials_unlit", "KHR_materials_sheen"};
  m.extensionsRequired = {"KHR_materials_unlit"};
  m.materials[0].extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
  const std::string path = Temp("strip_unlit.glb");
  WriteGltf(m, path);
  const Rig rig = LoadGltfRig(path);
  EXPECT_EQ(rig.NumFaces(), 4);
  EXPECT_EQ(rig.materials[0].texture, 0);
}

TEST(GltfExtensions, TextureTransformMovesTheUvs) {
  tinygltf::Model m = TinyStrip();
  tinygltf::Value::Object t;
  t["offset"] =
      tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(0.5), tinygltf::Value(0.25)});
  t["scale"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(2.0), tinygltf::Value(3.0)});
  t["rotation"] = tinygltf::Value(M_PI / 2);
  m.materials[0].pbrMetallicRoughness.baseColorTexture.extensions["KHR_texture_transform"] =
      tinygltf::Value(t);
  m.extensionsUsed = {"KHR_texture_transform"};
  m.extensionsRequired = {"KHR_texture_transform"};
  const std::string path = Temp("strip_transform.glb");
  WriteGltf(m, path);
  const Rig rig = LoadGltfRig(path);
  // uv' = T R S uv with R = [cos sin; -sin cos] (the extension's matrix):
  // for rotation pi/2, (u, v) -> (0.5 + 3 v, 0.25 - 2 u).
  for (int i = 0; i < rig.rest_vertices.cols(); ++i) {
    const double u = rig.rest_vertices(0, i), v = rig.rest_vertices(1, i) / 2;
    EXPECT_NEAR(rig.uvs(0, i), 0.5 + 3 * v, 1e-6);
    EXPECT_NEAR(rig.uvs(1, i), 0.25 - 2 * u, 1e-6);
  }
}

TEST(GltfAccessors, QuantizedPositionsAndTexcoords) {
  tinygltf::Model m = TinyStrip();
  tinygltf::Primitive& prim = m.meshes[0].primitives[0];
  // KHR_mesh_quantization: positions as SHORT (a real file scales them back
  // in its inverse bind matrices; here the rest mesh is just 1000 times
  // larger), UVs as normalised UNSIGNED_SHORT.
  prim.attributes["POSITION"] =
      AddAccessor(&m,
                  std::vector<int16_t>{0, 0, 0, 1000, 0, 0, 0, 1000, 0, 1000, 1000, 0, 0, 2000, 0,
                                       1000, 2000, 0},
                  TINYGLTF_TYPE_VEC3, TINYGLTF_COMPONENT_TYPE_SHORT);
  m.accessors.back().minValues = {0, 0, 0};
  m.accessors.back().maxValues = {1000, 2000, 0};
  prim.attributes["TEXCOORD_0"] = AddAccessor(
      &m, std::vector<uint16_t>{0, 0, 65535, 0, 0, 32768, 65535, 32768, 0, 65535, 65535, 65535},
      TINYGLTF_TYPE_VEC2, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, /*normalized=*/true);
  m.extensionsUsed = {"KHR_mesh_quantization"};
  m.extensionsRequired = {"KHR_mesh_quantization"};
  const std::string path = Temp("strip_quantized.glb");
  WriteGltf(m, path);
  const Rig rig = LoadGltfRig(path);
  EXPECT_DOUBLE_EQ(rig.rest_vertices(1, 5), 2000.0);
  EXPECT_NEAR(rig.uvs(1, 2), 32768 / 65535.0, 1e-7);
  EXPECT_NEAR(rig.uvs(0, 5), 1.0, 1e-7);
}

TEST(GltfAccessors, SparseAndBufferlessAccessors) {
  tinygltf::Model m = TinyStrip();
  // POSITION: no bufferView (zeros) with every vertex given sparsely, and a
  // morph target without bufferView moving vertex 5 only.
  tinygltf::Accessor pos = m.accessors[m.meshes[0].primitives[0].attributes["POSITION"]];
  pos.bufferView = -1;
  pos.sparse.isSparse = true;
  pos.sparse.count = 5;  // vertex 0 stays at the zero default
  pos.sparse.indices.bufferView = testing::AddView(&m, std::vector<uint8_t>{1, 2, 3, 4, 5});
  pos.sparse.indices.byteOffset = 0;
  pos.sparse.indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  pos.sparse.values.bufferView =
      testing::AddView(&m, std::vector<float>{1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0});
  pos.sparse.values.byteOffset = 0;
  m.accessors.push_back(pos);
  m.meshes[0].primitives[0].attributes["POSITION"] = static_cast<int>(m.accessors.size()) - 1;
  tinygltf::Accessor delta = pos;
  delta.sparse.count = 1;
  delta.minValues = {0, 0, 0};
  delta.maxValues = {0, 0, 0.5};
  delta.sparse.indices.bufferView = testing::AddView(&m, std::vector<uint16_t>{5, 0});
  delta.sparse.indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
  delta.sparse.values.bufferView = testing::AddView(&m, std::vector<float>{0, 0, 0.5f});
  m.accessors.push_back(delta);
  m.meshes[0].primitives[0].targets.push_back(
      {{"POSITION", static_cast<int>(m.accessors.size()) - 1}});
  m.meshes[0].weights = {1.0};
  const std::string path = Temp("strip_sparse.gltf");
  WriteGltf(m, path);
  const Rig rig = LoadGltfRig(path);
  WriteGltf(TinyStrip(), Temp("strip_ref.glb"));
  const Rig reference = LoadGltfRig(Temp("strip_ref.glb"));
  EXPECT_EQ((rig.rest_vertices - reference.rest_vertices).cwiseAbs().maxCoeff(), 0.0);
  ASSERT_EQ(rig.morph_groups.size(), 1u);
  EXPECT_EQ(rig.morph_groups[0].deltas[0](2, 5), 0.5);
  EXPECT_EQ(rig.morph_groups[0].deltas[0].col(4).norm(), 0.0);
}

TEST(GltfFiles, ExternalBinAndImagesAndDataUris) {
  WriteGltf(TinyStrip(), Temp("ref.glb"));
  const Rig reference = LoadGltfRig(Temp("ref.glb"));
  const std::string dir = Temp("external");
  std::filesystem::create_directories(dir);
  WriteGltf(TinyStrip(), dir + "/strip.gltf", /*embed=*/false);
  ASSERT_TRUE(std::filesystem::exists(dir + "/strip.bin"));
  ASSERT_TRUE(std::filesystem::exists(dir + "/checker.png"));
  const Rig external = LoadGltfRig(dir + "/strip.gltf");
  EXPECT_EQ(external.rest_vertices, reference.rest_vertices);
  ASSERT_EQ(external.textures.size(), 1u);
  EXPECT_EQ(cv::norm(external.textures[0], reference.textures[0], cv::NORM_INF), 0.0);
  // A missing .bin is an error naming the file it looked for.
  std::filesystem::remove(dir + "/strip.bin");
  EXPECT_NE(LoadError(dir + "/strip.gltf").find("strip.bin"), std::string::npos)
      << LoadError(dir + "/strip.gltf");
  // Data URIs (everything inside the .gltf).
  WriteGltf(TinyStrip(), Temp("embedded.gltf"), /*embed=*/true);
  const Rig embedded = LoadGltfRig(Temp("embedded.gltf"));
  EXPECT_EQ(embedded.rest_vertices, reference.rest_vertices);
  EXPECT_EQ(embedded.animations.size(), 1u);
}

TEST(GltfSkins, OneSkinPerMesh) {
  // As three.js writes it: two meshes, each with its own skin over the same
  // joints (the second skin's bind pose shifted by 3 along x).
  tinygltf::Model m = TinyStrip();
  tinygltf::Skin second = m.skins[0];
  std::vector<float> ibm(32, 0.0f);
  for (int j = 0; j < 2; ++j) {
    for (int k = 0; k < 4; ++k) ibm[16 * j + 5 * k] = 1;
    ibm[16 * j + 12] = -3;
  }
  ibm[16 + 13] = -1;
  second.inverseBindMatrices =
      AddAccessor(&m, ibm, TINYGLTF_TYPE_MAT4, TINYGLTF_COMPONENT_TYPE_FLOAT);
  m.skins.push_back(second);
  tinygltf::Mesh mesh = m.meshes[0];
  tinygltf::Primitive& prim = mesh.primitives[0];
  prim.attributes["POSITION"] =
      AddAccessor(&m, std::vector<float>{3, 0, 0, 4, 0, 0, 3, 1, 0, 4, 1, 0, 3, 2, 0, 4, 2, 0},
                  TINYGLTF_TYPE_VEC3, TINYGLTF_COMPONENT_TYPE_FLOAT);
  m.accessors.back().minValues = {3, 0, 0};
  m.accessors.back().maxValues = {4, 2, 0};
  m.meshes.push_back(mesh);
  tinygltf::Node body2;
  body2.name = "body2";
  body2.mesh = 1;
  body2.skin = 1;
  body2.translation = {10, 0, 0};  // ignored for skinned meshes (spec)
  m.nodes.push_back(body2);
  m.scenes[0].nodes.push_back(3);
  const std::string path = Temp("two_skins.glb");
  WriteGltf(m, path);
  const Rig rig = LoadGltfRig(path);
  EXPECT_EQ(rig.NumFaces(), 8);
  EXPECT_EQ(rig.influences.size(), 4u);
  // Both meshes follow the same joints: posed, the second copy lies on the first.
  const Eigen::Matrix3Xd posed = PoseRig(rig, &rig.animations[0], 1.0);
  EXPECT_LT((posed.leftCols(6) - posed.rightCols(6)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(posed(0, 4), -1.0, 1e-6);  // the tip turned by 90 degrees: (0, 2) -> (-1, 1)
  EXPECT_NEAR(posed(1, 4), 1.0, 1e-6);
}

}  // namespace
}  // namespace banmo::synth
