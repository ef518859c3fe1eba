// Runs the built `banmo extract` on a checkpoint and checks its files against
// the library, and its errors (exit code 2, a message naming the input,
// nothing written).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "banmo/extract/extract.h"
#include "banmo/geometry/mesh_io.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/config.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

RunResult RunExtract(const std::string& args) {
  const std::string command = std::string(BANMO_BINARY) + " extract " + args + " 2>&1";
  RunResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.output.append(buffer, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

class ExtractCli : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("banmo_extract_cli_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    config_ = LoadSolverConfig(std::string(BANMO_SOURCE_DIR) + "/problems/tiny.yaml");
    config_.model.num_bones = 3;
    PinholeCamera camera;
    camera.width = camera.height = 32;
    camera.intrinsics = Eigen::Vector4d(30, 30, 16, 16);
    model_ = std::make_unique<Model>(config_.model, std::vector<int>{2, 3},
                                     std::vector<PinholeCamera>{camera, camera});
    // Frame 1:2 posed: a root pose in front of the camera and one bone moved.
    FrameParameters& f = model_->frame(1, 2);
    f.root_init = PoseFromAngleAxis(Eigen::Vector3d(0.1, 0.2, 0.0), Eigen::Vector3d(0, 0, 3));
    const Pose bone = PoseFromAngleAxis(Eigen::Vector3d(0, 0, 0.3), Eigen::Vector3d(0.05, 0, 0));
    std::copy(bone.data(), bone.data() + kPoseSize, f.bones_t.data() + kPoseSize);
    CheckpointInfo info;
    info.config = SolverConfigToYaml(config_);
    SaveCheckpoint((root_ / "model").string(), *model_, info);
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path root_;
  SolverConfig config_;
  std::unique_ptr<Model> model_;
};

TEST_F(ExtractCli, WritesTheLibraryResult) {
  const fs::path out = root_ / "out";
  const RunResult r = RunExtract("--model " + (root_ / "model").string() + " --out " +
                                 out.string() + " --resolution 32 --frames 1:1-2,0:0");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("canonical mesh"), std::string::npos) << r.output;
  ExtractOptions options;
  options.grid.resolution = 32;
  const TriangleMesh canonical = ExtractCanonicalMesh(*model_, options);
  const TriangleMesh read = ReadMesh((out / "canonical.ply").string());
  ASSERT_EQ(read.NumVertices(), canonical.NumVertices());
  ASSERT_EQ(read.NumFaces(), canonical.NumFaces());
  // PLY stores doubles: equal up to the batch rounding of the MLP (the
  // command may use another thread count).
  EXPECT_LT((read.vertices - canonical.vertices).cwiseAbs().maxCoeff(), 1e-12);
  const TriangleMesh posed = ReadMesh((out / "frames/video01_frame00002.ply").string());
  const TriangleMesh expected = ArticulateMesh(*model_, canonical, 1, 2);
  ASSERT_EQ(posed.NumVertices(), expected.NumVertices());
  EXPECT_LT((posed.vertices - expected.vertices).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT(posed.vertices.row(2).minCoeff(), 1.0);  // in front of the camera
  EXPECT_TRUE(fs::exists(out / "frames/video01_frame00001.ply"));
  EXPECT_TRUE(fs::exists(out / "frames/video00_frame00000.ply"));
  EXPECT_FALSE(fs::exists(out / "frames/video00_frame00001.ply"));
  for (const char* name :
       {"bones.ply", "skinning.ply", "skinning_weights.npy", "embedding.npy", "extract.json"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
}

// Without --bounds the command samples the box stored with the model (the
// box training sampled); here it cuts the initial sphere at x = -0.3.
TEST_F(ExtractCli, SamplesTheModelsTrainedBoxByDefault) {
  const Eigen::AlignedBox3d trained(Eigen::Vector3d(-0.3, -0.9, -0.9),
                                    Eigen::Vector3d(0.9, 0.9, 0.9));
  model_->set_canonical_bounds(trained);
  CheckpointInfo info;
  info.config = SolverConfigToYaml(config_);
  SaveCheckpoint((root_ / "boxed").string(), *model_, info);
  const fs::path out = root_ / "out_boxed";
  const RunResult r = RunExtract("--model " + (root_ / "boxed").string() + " --out " +
                                 out.string() + " --resolution 24 --frames none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ExtractOptions options;
  options.grid.resolution = 24;
  options.grid.bounds_min = trained.min();
  options.grid.bounds_max = trained.max();
  const TriangleMesh expected = ExtractCanonicalMesh(*model_, options);
  const TriangleMesh read = ReadMesh((out / "canonical.ply").string());
  ASSERT_EQ(read.NumVertices(), expected.NumVertices());
  EXPECT_LT((read.vertices - expected.vertices).cwiseAbs().maxCoeff(), 1e-12);
  // The sphere would reach x = -0.5 in the unit cube; the mesh ends at the
  // cut, within one cell (1.8 / 24 = 0.075) of it.
  EXPECT_GE(read.vertices.row(0).minCoeff(), -0.3 - 1e-12);
  EXPECT_LT(read.vertices.row(0).minCoeff(), -0.3 + 0.075);
}

// --level extracts another level set of the SDF, as the library does; a
// level inside the surface gives a smaller mesh.
TEST_F(ExtractCli, ExtractsTheLevelAskedFor) {
  const fs::path out = root_ / "out_level";
  const RunResult r = RunExtract("--model " + (root_ / "model").string() + " --out " +
                                 out.string() + " --resolution 32 --frames none --level=-0.1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ExtractOptions options;
  options.grid.resolution = 32;
  options.grid.iso_level = -0.1;
  const TriangleMesh expected = ExtractCanonicalMesh(*model_, options);
  const TriangleMesh read = ReadMesh((out / "canonical.ply").string());
  ASSERT_EQ(read.NumVertices(), expected.NumVertices());
  EXPECT_LT((read.vertices - expected.vertices).cwiseAbs().maxCoeff(), 1e-12);
  options.grid.iso_level = 0.0;
  const TriangleMesh zero = ExtractCanonicalMesh(*model_, options);
  const auto extent = [](const TriangleMesh& m) {
    return (m.vertices.rowwise().maxCoeff() - m.vertices.rowwise().minCoeff()).eval();
  };
  EXPECT_LT(extent(read)[0], extent(zero)[0] - 0.1);  // 0.1 inside on both sides
  const RunResult bad = RunExtract("--model " + (root_ / "model").string() + " --out " +
                                   (root_ / "out_bad_level").string() + " --level nan");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("iso_level"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(root_ / "out_bad_level"));
}

TEST_F(ExtractCli, BadInputsExitWithTwoAndWriteNothing) {
  const std::string model = " --model " + (root_ / "model").string();
  const fs::path out = root_ / "bad_out";
  const std::string out_arg = " --out " + out.string();
  struct Case {
    std::string args;
    std::string expect;  // in the message
  };
  const Case cases[] = {
      {" --model " + (root_ / "nope").string() + out_arg, "nope"},
      {model + out_arg + " --frames 2:0", "--frames"},
      {model + out_arg + " --frames 0:5", "--frames"},
      {model + out_arg + " --bounds 1,2,3", "--bounds"},
      {model + out_arg + " --bounds 0,0,0,1,x,1", "--bounds"},
      {model + out_arg + " --resolution 1", "resolution"},
      {model + out_arg + " --coarse-stride 0", "coarse_stride"},
      {model + out_arg + " --min-component-fraction 1.5", "min_component_fraction"},
      {model + out_arg + " --min-component-fraction -0.1", "min_component_fraction"},
      {model + out_arg + " --bounds 2,2,2,3,3,3", "no zero crossing"},
  };
  for (const Case& c : cases) {
    const RunResult r = RunExtract(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find("error:"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
  // A parameter file of the wrong size names the file.
  {
    std::FILE* f = std::fopen((root_ / "model/params.bin").c_str(), "ab");
    ASSERT_NE(f, nullptr);
    std::fputc(0, f);
    std::fclose(f);
  }
  const RunResult r = RunExtract(model + out_arg);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("params.bin"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace banmo
