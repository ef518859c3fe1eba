// glTF files made to break the loader (issue 66): node graphs with cycles,
// URIs that leave the glTF's folder, FIFOs where files belong, and skins
// whose joints bind the mesh through a 100x scale as FBX2glTF writes them.
// Every file is made at test time; inputs that could block run in a child
// process with a time limit.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "../common/timeout.h"
#include "banmo/io/codecs.h"
#include "banmo/synth/gltf_rig.h"
#include "banmo/synth/scene.h"
#include "banmo/util/error.h"
#include "gltf_files.h"

namespace banmo::synth {
namespace {

namespace fs = std::filesystem;
using testing::TinyStrip;
using testing::WriteGltf;

std::string Temp(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/gltf_hostile_test";
  fs::create_directories(dir);
  return dir + "/" + name;
}

std::string LoadError(const std::string& path) {
  try {
    LoadGltfRig(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

TEST(GltfNodeGraph, SelfChildIsRefusedByName) {
  tinygltf::Model m = TinyStrip();
  m.nodes[1].children = {1};
  const std::string path = Temp("self_child.glb");
  WriteGltf(m, path);
  const std::string error = LoadError(path);
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find("node 1 ('tip') lists itself as a child"), std::string::npos) << error;
}

TEST(GltfNodeGraph, CycleIsRefusedByName) {
  // root -> tip -> root: each node has one parent, the graph is no tree.
  tinygltf::Model m = TinyStrip();
  m.nodes[1].children = {0};
  const std::string path = Temp("cycle.glb");
  WriteGltf(m, path);
  const std::string error = LoadError(path);
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find("the node graph has a cycle"), std::string::npos) << error;
}

// A folder `dir` with strip.gltf whose buffer is strip.bin and image
// checker.png, all beside it; returns the path of the .gltf.
std::string ExternalStrip(const std::string& dir) {
  fs::remove_all(dir);
  fs::create_directories(dir);
  WriteGltf(TinyStrip(), dir + "/strip.gltf", /*embed=*/false);
  return dir + "/strip.gltf";
}

// Sets buffers[0].uri (or images[0].uri) of the .gltf at `path`.
void SetUri(const std::string& path, const char* list, const std::string& uri) {
  nlohmann::json doc = nlohmann::json::parse(ReadText(path));
  doc[list][0]["uri"] = uri;
  WriteText(path, doc.dump(1));
}

TEST(GltfUris, OnlyFilesInsideTheGltfsFolderAreOpened) {
  const std::string outside = Temp("uris");
  const std::string dir = outside + "/model";
  const std::string gltf = ExternalStrip(dir);
  ASSERT_EQ(LoadError(gltf), "");
  // A copy of the buffer outside the folder, which must never be read.
  fs::copy_file(dir + "/strip.bin", outside + "/strip.bin", fs::copy_options::overwrite_existing);
  fs::copy_file(dir + "/checker.png", outside + "/checker.png",
                fs::copy_options::overwrite_existing);
  const std::string absolute = fs::absolute(outside + "/strip.bin").string();
  const struct {
    const char* list;
    std::string uri;
    const char* expect;
  } cases[] = {
      {"buffers", "../strip.bin", "'..' may not leave"},
      {"buffers", "%2E%2E/strip.bin", "'..' may not leave"},
      {"buffers", "strip.bin%zz../x", "contains a NUL character"},
      {"buffers", "sub/../../strip.bin", "'..' may not leave"},
      {"buffers", absolute, "absolute paths are not allowed"},
      {"buffers", "file://" + absolute, "URI schemes"},
      {"buffers", ".", "names no file"},
      {"buffers", "", "names no file"},
      {"images", "../checker.png", "'..' may not leave"},
      {"images", "file:checker.png", "URI schemes"},
  };
  for (const auto& c : cases) {
    ExternalStrip(dir);
    SetUri(gltf, c.list, c.uri);
    const std::string error = LoadError(gltf);
    EXPECT_NE(error.find(gltf), std::string::npos) << c.uri << ": " << error;
    EXPECT_NE(error.find(std::string(c.list) + "[0].uri"), std::string::npos)
        << c.uri << ": " << error;
    EXPECT_NE(error.find(c.expect), std::string::npos) << c.uri << ": " << error;
  }
  // A symbolic link inside the folder that points outside it.
  ExternalStrip(dir);
  fs::create_symlink(outside + "/strip.bin", dir + "/link.bin");
  SetUri(gltf, "buffers", "link.bin");
  EXPECT_NE(LoadError(gltf).find("resolves outside the glTF's folder"), std::string::npos)
      << LoadError(gltf);
  // Inside the folder, in a subfolder: accepted.
  ExternalStrip(dir);
  fs::create_directories(dir + "/data");
  fs::rename(dir + "/strip.bin", dir + "/data/strip.bin");
  SetUri(gltf, "buffers", "data/strip.bin");
  EXPECT_EQ(LoadError(gltf), "");
}

TEST(GltfUris, FifosAreRefusedWithoutBlocking) {
  const std::string dir = Temp("fifo");
  const std::string gltf = ExternalStrip(dir);
  ASSERT_EQ(::mkfifo((dir + "/fifo.bin").c_str(), 0600), 0);
  SetUri(gltf, "buffers", "fifo.bin");
  const auto buffer = banmo::testing::ErrorOfWithTimeout([&] { LoadGltfRig(gltf); });
  ASSERT_TRUE(buffer.finished) << "loading a glTF whose buffer is a FIFO hung";
  EXPECT_NE(buffer.message.find("buffers[0].uri 'fifo.bin'"), std::string::npos) << buffer.message;
  EXPECT_NE(buffer.message.find("not a regular file"), std::string::npos) << buffer.message;
  // The glTF file itself a FIFO.
  ASSERT_EQ(::mkfifo((dir + "/pipe.glb").c_str(), 0600), 0);
  const auto file = banmo::testing::ErrorOfWithTimeout([&] { LoadGltfRig(dir + "/pipe.glb"); });
  ASSERT_TRUE(file.finished) << "loading a FIFO as a .glb hung";
  EXPECT_NE(file.message.find(dir + "/pipe.glb: is a FIFO"), std::string::npos) << file.message;
}

// TinyStrip as FBX2glTF would write it: POSITIONs in a "mesh space" M^-1
// away from the bind pose, and inverse bind matrices IBM * M, so that at the
// rest pose every joint maps the mesh by M (a 90 degree turn, 100x scale).
tinygltf::Model StripWithBindOffset() {
  tinygltf::Model m = TinyStrip();
  Eigen::Matrix4d offset = Eigen::Matrix4d::Identity();
  offset.topLeftCorner<3, 3>() =
      100.0 * Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix4d inverse = offset.inverse();
  const tinygltf::Primitive& prim = m.meshes[0].primitives[0];
  auto floats = [&](int accessor) {
    const tinygltf::Accessor& a = m.accessors[accessor];
    const tinygltf::BufferView& v = m.bufferViews[a.bufferView];
    return reinterpret_cast<float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
  };
  float* pos = floats(prim.attributes.at("POSITION"));
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d p =
        (inverse * Eigen::Vector4d(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2], 1)).head<3>();
    for (int k = 0; k < 3; ++k) pos[3 * i + k] = static_cast<float>(p[k]);
  }
  tinygltf::Accessor& pa = m.accessors[prim.attributes.at("POSITION")];
  pa.minValues = {-1e9, -1e9, -1e9};  // loose bounds (only checked to contain)
  pa.maxValues = {1e9, 1e9, 1e9};
  float* ibm = floats(m.skins[0].inverseBindMatrices);
  for (int j = 0; j < 2; ++j) {
    Eigen::Matrix4d b;
    for (int k = 0; k < 16; ++k) b(k % 4, k / 4) = ibm[16 * j + k];
    b = b * offset;
    for (int k = 0; k < 16; ++k) ibm[16 * j + k] = static_cast<float>(b(k % 4, k / 4));
  }
  return m;
}

TEST(GltfSkins, BindOffsetOfFbx2gltfFilesIsMovedIntoTheRestVertices) {
  WriteGltf(TinyStrip(), Temp("plain.glb"));
  WriteGltf(StripWithBindOffset(), Temp("offset.glb"));
  const Rig plain = LoadGltfRig(Temp("plain.glb"));
  const Rig offset = LoadGltfRig(Temp("offset.glb"));
  // Float32 positions and inverse binds through a 100x scale: 1e-5 relative.
  EXPECT_LE((plain.rest_vertices - offset.rest_vertices).cwiseAbs().maxCoeff(), 1e-5);
  for (double t : {0.0, 0.5, 1.0}) {
    const Eigen::Matrix3Xd a = PoseRig(plain, &plain.animations[0], t);
    const Eigen::Matrix3Xd b = PoseRig(offset, &offset.animations[0], t);
    EXPECT_LE((a - b).cwiseAbs().maxCoeff(), 1e-5) << "t = " << t;
  }
  // The rest vertices are the rest pose, so the scene is framed and every
  // flow is finite (it was not: the posed mesh was 100x the normalised one).
  SynthOptions o;
  o.num_videos = 1;
  o.frames_per_video = 4;
  o.image_size = 32;
  o.flow_gaps = {1, 2};
  const SynthScene scene = RenderSyntheticScene(offset, o);
  int object_pixels = 0;
  for (const Frame& f : scene.dataset.videos[0].frames) {
    object_pixels += cv::countNonZero(f.mask);
    for (const FlowField& flow : f.flows) EXPECT_TRUE(AllFinite(flow.flow)) << f.index;
  }
  EXPECT_GT(object_pixels, 4 * 32);
}

// A point that is visible in one frame and behind the camera in another:
// its flow is invalid and finite (was +-inf in half floats).
TEST(SceneFlow, PointsBehindTheCameraHaveFiniteInvalidFlow) {
  tinygltf::Model m = TinyStrip();
  // The tip swings 40 units towards and past the camera and back.
  const std::vector<float> times = {0, 1, 2};
  const std::vector<float> moves = {0, 1, 0, 0, 1, 40, 0, 1, 0};
  tinygltf::AnimationSampler sampler;
  sampler.input =
      testing::AddAccessor(&m, times, TINYGLTF_TYPE_SCALAR, TINYGLTF_COMPONENT_TYPE_FLOAT);
  m.accessors.back().minValues = {0};
  m.accessors.back().maxValues = {2};
  sampler.output =
      testing::AddAccessor(&m, moves, TINYGLTF_TYPE_VEC3, TINYGLTF_COMPONENT_TYPE_FLOAT);
  sampler.interpolation = "LINEAR";
  tinygltf::AnimationChannel channel;
  channel.sampler = 0;
  channel.target_node = 1;
  channel.target_path = "translation";
  tinygltf::Animation anim;
  anim.name = "lunge";
  anim.samplers.push_back(sampler);
  anim.channels.push_back(channel);
  m.animations = {anim};
  WriteGltf(m, Temp("lunge.glb"));
  const Rig rig = LoadGltfRig(Temp("lunge.glb"));
  SynthOptions o;
  o.num_videos = 2;
  o.frames_per_video = 12;
  o.image_size = 32;
  o.flow_gaps = {1, 2, 4};
  o.fps = 6;
  const SynthScene scene = RenderSyntheticScene(rig, o);
  for (const Video& v : scene.dataset.videos) {
    for (const Frame& f : v.frames) {
      for (const FlowField& flow : f.flows) {
        EXPECT_TRUE(AllFinite(flow.flow)) << v.name << " frame " << f.index << " gap " << flow.gap;
      }
    }
  }
}

}  // namespace
}  // namespace banmo::synth
