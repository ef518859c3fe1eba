// Runs the built `banmo eval` and checks exit codes, messages and outputs.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "../common/run_banmo.h"
#include "../io/test_dataset_util.h"
#include "banmo/geometry/mesh_io.h"
#include "test_shapes.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

using testing::CommandResult;
using testing::ReadText;

CommandResult RunEval(const std::string& args) { return testing::RunBanmo("eval " + args); }

// Writes a binary PLY by hand (WritePly refuses non-finite vertices).
void WriteRawPly(const fs::path& path, const Eigen::Matrix3Xd& vertices,
                 const Eigen::Matrix3Xi& faces) {
  std::ofstream out(path, std::ios::binary);
  out << "ply\nformat binary_little_endian 1.0\nelement vertex " << vertices.cols()
      << "\nproperty double x\nproperty double y\nproperty double z\nelement face " << faces.cols()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  out.write(reinterpret_cast<const char*>(vertices.data()),
            static_cast<std::streamsize>(sizeof(double) * vertices.size()));
  for (Eigen::Index f = 0; f < faces.cols(); ++f) {
    const unsigned char three = 3;
    out.write(reinterpret_cast<const char*>(&three), 1);
    out.write(reinterpret_cast<const char*>(faces.col(f).data()), 3 * sizeof(int));
  }
}

class EvalCli : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("banmo_eval_cli_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "gt");
    fs::create_directories(root_ / "pred");
    const Eigen::Vector3d center(0.0, 0.0, 3.0);
    for (int i = 0; i < 3; ++i) {
      const TriangleMesh gt = testing::Blob(center + Eigen::Vector3d(0.1 * i, 0, 0), 16, 32);
      // A perturbed copy: slightly larger, rotated about the viewing axis.
      const TriangleMesh pred =
          testing::Transformed(gt, 1.0 + 0.01 * i, testing::Rotation(3.0, Eigen::Vector3d(0, 0, 1)),
                               Eigen::Vector3d(0.01, 0, 0));
      WritePly((root_ / "gt" / ("frame_" + std::to_string(i) + ".ply")).string(), gt);
      WriteObj((root_ / "pred" / ("frame_" + std::to_string(i) + ".obj")).string(), pred);
    }
  }
  void TearDown() override { fs::remove_all(root_); }
  std::string Path(const std::string& rel) const { return (root_ / rel).string(); }

  fs::path root_;
};

TEST_F(EvalCli, WritesTableCsvAndJson) {
  for (const std::string protocol : {"banmo", "surface"}) {
    const std::string out = Path("out_" + protocol);
    const CommandResult r = RunEval("--pred " + Path("pred") + " --gt " + Path("gt") +
                                    " --protocol " + protocol + " --samples 3000 --out " + out);
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("CD(cm)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("mean"), std::string::npos);
    const std::string json = ReadText(out + "/summary.json");
    for (const char* key : {"\"chamfer_cm\"", "\"fscore_1\"", "\"fscore_2\"", "\"fscore_5\"",
                            "\"frames\": 3", "\"worst_frame\"", "\"protocol\""}) {
      EXPECT_NE(json.find(key), std::string::npos) << key << "\n" << json;
    }
    const std::string csv = ReadText(out + "/per_frame.csv");
    EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 4) << csv;  // header + 3 frames
    EXPECT_EQ(csv.rfind("frame,pred,gt,chamfer_cm", 0), 0u);
    // No temporary files left behind.
    for (const auto& entry : fs::directory_iterator(out)) {
      EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos);
    }
  }
}

TEST_F(EvalCli, SingleFilesWork) {
  const CommandResult r =
      RunEval("--pred " + Path("pred/frame_0.obj") + " --gt " + Path("gt/frame_0.ply"));
  EXPECT_EQ(r.exit_code, 0) << r.out;
}

TEST_F(EvalCli, MismatchedFrameCounts) {
  const CommandResult r = RunEval("--pred " + Path("pred/frame_0.obj") + " --gt " + Path("gt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("frame counts differ"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("did you mean"), std::string::npos) << r.out;
}

// `banmo solve` writes per-frame meshes to OUT/meshes/frames/; passing
// OUT/meshes instead gets a hint.
TEST_F(EvalCli, MismatchHintsAtFramesFolder) {
  const fs::path meshes = root_ / "solve_out" / "meshes";
  fs::create_directories(meshes / "frames");
  fs::copy_file(root_ / "pred" / "frame_0.obj", meshes / "canonical.obj");
  const CommandResult r = RunEval("--pred " + meshes.string() + " --gt " + Path("gt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("did you mean --pred " + (meshes / "frames").string() + "?"),
            std::string::npos)
      << r.out;
}

TEST_F(EvalCli, EmptyMesh) {
  const fs::path empty = root_ / "gt" / "frame_1.ply";
  WriteRawPly(empty, Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0));
  const CommandResult r = RunEval("--pred " + Path("pred") + " --gt " + Path("gt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find(empty.string()), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no vertices"), std::string::npos) << r.out;
}

TEST_F(EvalCli, NanVertex) {
  Eigen::Matrix3Xd v(3, 3);
  v << 0, 1, 0, 0, 0, 1, 3, 3, std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix3Xi f(3, 1);
  f << 0, 1, 2;
  const fs::path bad = root_ / "pred" / "frame_2.ply";
  fs::remove(root_ / "pred" / "frame_2.obj");
  WriteRawPly(bad, v, f);
  const CommandResult r = RunEval("--pred " + Path("pred") + " --gt " + Path("gt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find(bad.string() + ": vertex 2 has a non-finite coordinate"), std::string::npos)
      << r.out;
}

TEST_F(EvalCli, UnreadableAndMissingFiles) {
  const fs::path garbage = root_ / "gt" / "frame_0.ply";
  std::ofstream(garbage) << "this is not a ply file\n";
  CommandResult r = RunEval("--pred " + Path("pred") + " --gt " + Path("gt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find(garbage.string()), std::string::npos) << r.out;
  r = RunEval("--pred " + Path("nowhere") + " --gt " + Path("gt"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("nowhere: does not exist"), std::string::npos) << r.out;
  r = RunEval("--pred " + Path("pred") + " --gt " + Path("gt") + " --protocol chamfer");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("--protocol: unknown protocol 'chamfer'"), std::string::npos);
  r = RunEval("--pred " + Path("pred"));  // --gt missing: CLI11 usage error
  EXPECT_NE(r.exit_code, 0);
}

// --gt may be a banmo dataset folder: its gt_mesh/ files, video by video.
TEST_F(EvalCli, DatasetAsGroundTruth) {
  Dataset dataset = testing::MakeSmallDataset(24, 20, /*frames=*/2);
  std::vector<std::vector<TriangleMesh>> meshes(dataset.videos.size());
  fs::create_directories(root_ / "pred4");
  int k = 0;
  for (std::size_t v = 0; v < dataset.videos.size(); ++v) {
    for (std::size_t t = 0; t < dataset.videos[v].frames.size(); ++t, ++k) {
      meshes[v].push_back(testing::Blob(Eigen::Vector3d(0.05 * k, 0, 3), 16, 32));
      WritePly((root_ / "pred4" / ("p" + std::to_string(k) + ".ply")).string(), meshes[v].back());
    }
  }
  const std::string dir = Path("dataset");
  WriteDataset(dataset, dir, &meshes);
  CommandResult r = RunEval("--pred " + Path("pred4") + " --gt " + dir + " --out " + Path("out"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("4 frame(s)"), std::string::npos) << r.out;
  const std::string json = ReadText(Path("out/summary.json"));
  // Identical meshes: 0 up to rounding (the dense ground truth's closest
  // points on the triangles are computed, not copied: ~1e-13 cm).
  const std::size_t at = json.find("\"chamfer_cm\": ");
  ASSERT_NE(at, std::string::npos) << json;
  EXPECT_LT(std::stod(json.substr(at + 14)), 1e-9) << json;
  EXPECT_NE(json.find("\"gt_mode\": \"dense\""), std::string::npos) << json;
  EXPECT_NE(r.out.find("protocol: banmo, ground truth dense"), std::string::npos) << r.out;
  // Frame count mismatch against the dataset.
  r = RunEval("--pred " + Path("pred") + " --gt " + dir);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("frame counts differ"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace banmo
