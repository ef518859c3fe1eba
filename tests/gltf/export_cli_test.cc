// Runs the built `banmo export` on a checkpoint: the file it writes loads,
// validates and has the model's animations; bad inputs exit with 2, print
// "error: ..." naming the input, and write nothing.
#include <gtest/gtest.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "../common/run_banmo.h"
#include "banmo/extract/extract.h"
#include "banmo/gltf/export.h"
#include "banmo/gltf/validate.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/config.h"
#include "gltf_test_util.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing::RunBanmo;

class ExportCli : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("banmo_export_cli_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "out");
    model_ = testing::MakeExportTestModel(5, 21);
    SolverConfig config = LoadSolverConfig(std::string(BANMO_SOURCE_DIR) + "/problems/tiny.yaml");
    config.model = model_->options();
    CheckpointInfo info;
    info.config = SolverConfigToYaml(config);
    SaveCheckpoint((root_ / "model").string(), *model_, info);
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path root_;
  std::unique_ptr<Model> model_;
};

TEST_F(ExportCli, WritesAValidAnimatedGlb) {
  const fs::path out = root_ / "out" / "fox.glb";
  const auto r = RunBanmo("export --model " + (root_ / "model").string() + " --out " +
                          out.string() + " --resolution 32 --fps 5 --video-names a,b");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("wrote"), std::string::npos) << r.out;
  tinygltf::Model gltf;
  ReadGltf(out.string(), &gltf);
  EXPECT_TRUE(ValidateGltf(gltf).empty());
  ASSERT_EQ(gltf.animations.size(), 2u);
  EXPECT_EQ(gltf.animations[0].name, "a");
  EXPECT_EQ(gltf.animations[1].name, "b");
  // Posed at key 2 of video 1 (t = 2 / 5 s): the model's articulated mesh
  // (5 bones: top-4 truncation, bounded as in export_test; here a loose
  // check that the file is the checkpoint's model, not another).
  ExtractOptions e;
  e.grid.resolution = 32;
  const TriangleMesh canonical = ExtractCanonicalMesh(*model_, e);
  const Eigen::Matrix3Xd posed =
      testing::GltfToOpenCv(testing::SpecPosedPositions(gltf, 1, testing::KeyTime(2, 5)));
  ASSERT_EQ(posed.cols(), canonical.NumVertices());
  const Eigen::Matrix3Xd full = ArticulateMesh(*model_, canonical, 1, 2).vertices;
  EXPECT_LT((posed - full).colwise().norm().maxCoeff(), 0.02);
}

TEST_F(ExportCli, HelpDescribesTheCommand) {
  const auto r = RunBanmo("export --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* s :
       {"--model", "--out", "--resolution", "--fps", "--interpolation", "Blender"}) {
    EXPECT_NE(r.out.find(s), std::string::npos) << s;
  }
}

TEST_F(ExportCli, BadInputsExitWithTwoAndWriteNothing) {
  const std::string model = " --model " + (root_ / "model").string();
  const fs::path out = root_ / "out" / "x.glb";
  const std::string out_arg = " --out " + out.string();
  // A folder that is not a checkpoint, and a file used as a folder.
  fs::create_directories(root_ / "not_a_checkpoint");
  std::ofstream(root_ / "a_file") << "x";
  struct Case {
    std::string args;
    std::string expect;  // in the message
  };
  const Case cases[] = {
      {" --model " + (root_ / "nope").string() + out_arg, "nope"},
      {" --model " + (root_ / "not_a_checkpoint").string() + out_arg, "not_a_checkpoint"},
      {model + " --out " + (root_ / "missing" / "x.glb").string(), "missing"},
      {model + " --out " + (root_ / "a_file" / "x.glb").string(), "a_file"},
      {model + " --out " + (root_ / "out" / "x.obj").string(), ".glb or .gltf"},
      {model + " --out " + (root_ / "out").string(), "--out"},
      {model + out_arg + " --fps 0", "--fps"},
      {model + out_arg + " --resolution 1", "--resolution"},
      {model + out_arg + " --interpolation cubic", "--interpolation"},
      {model + out_arg + " --video-names a", "--video-names"},
      {model + out_arg + " --color-video -2", "--color-video"},
  };
  for (const Case& c : cases) {
    const auto r = RunBanmo("export" + c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find("error:"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(c.expect), std::string::npos) << c.args << "\n" << r.out;
    EXPECT_TRUE(fs::is_empty(root_ / "out")) << c.args;
  }
  // A damaged checkpoint names its file.
  std::ofstream(root_ / "model" / "params.bin", std::ios::app) << '\0';
  const auto r = RunBanmo("export" + model + out_arg);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("params.bin"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::is_empty(root_ / "out"));
}

}  // namespace
}  // namespace banmo
