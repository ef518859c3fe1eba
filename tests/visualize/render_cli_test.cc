// `banmo render` end to end: a dataset on disk (the tiny quadruped scene), a
// checkpoint written by `banmo solve` with a short config, then the render
// command; and its errors (exit status 2, a message naming the file or flag,
// nothing written).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <utility>
#include <vector>

#include "../common/run_banmo.h"
#include "../optim/tiny_solver_scene.h"
#include "banmo/io/dataset.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/config.h"
#include "banmo/optim/solver.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing::RunBanmo;

// A short solve: the tiny model of tests/optim, 30 Adam batches (enough for
// a checkpoint the renderer can read; quality is tested in visualize_test).
constexpr char kConfig[] = R"(model:
  num_bones: 4
  field:
    position_encoding: {num_bands: 4}
    sdf_width: 32
    sdf_layers: 2
    color_width: 16
    color_layers: 1
    embedding_width: 16
    embedding_layers: 1
    appearance_code_dim: 2
seed: 3
stages:
  - name: tiny
    batches: 30
    batch_rays: 96
    samples_per_ray: 16
    sampling: {flow_gaps: [1, 2], eikonal_points: 32, match_grid_points: 256, match_top_k: 8}
)";

// One dataset and an untrained checkpoint (written in-process: cheap) for
// the whole program; the first test trains its own with `banmo solve`.
class RenderCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = new fs::path(fs::temp_directory_path() /
                         ("banmo_render_cli_" + std::to_string(::getpid())));
    fs::remove_all(*root_);
    fs::create_directories(*root_);
    WriteDataset(testing::TinyQuadrupedDataset(), (*root_ / "data").string());
    const std::unique_ptr<banmo::Model> model = MakeModelForDataset(
        testing::TinyQuadrupedDataset(), ParseSolverConfig(kConfig, "kConfig").model);
    // The sampling of kConfig's stage, as the solver records it.
    model->set_training_sampling(TrainingSampling{16, 0.2, false});
    CheckpointInfo info;
    info.config = SolverConfigToYaml(ParseSolverConfig(kConfig, "kConfig"));
    SaveCheckpoint((*root_ / "untrained").string(), *model, info);
  }
  static void TearDownTestSuite() {
    fs::remove_all(*root_);
    delete root_;
  }
  static std::string Path(const std::string& name) { return (*root_ / name).string(); }
  static std::string Model() { return Path("untrained"); }
  static std::string Data() { return Path("data"); }

  static fs::path* root_;
};
fs::path* RenderCli::root_ = nullptr;

TEST_F(RenderCli, RendersTheCheckpointOfBanmoSolve) {
  std::ofstream(Path("tiny.yaml")) << kConfig;
  const auto solve = RunBanmo("solve --data " + Data() + " --config " + Path("tiny.yaml") +
                              " --out " + Path("solve") + " --no-extract --no-eval --quiet");
  ASSERT_EQ(solve.exit_code, 0) << solve.out;
  const std::string out = Path("out");
  const auto r =
      RunBanmo("render --model " + Path("solve/checkpoint") + " --data " + Data() + " --out " +
               out + " --frames 0:0,1:4-5 --scale 2 --mesh-resolution 48 --turntable 2");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("[3/3] video 1 frame 5"), std::string::npos) << r.out;  // progress
  EXPECT_NE(r.out.find("16 samples per ray"), std::string::npos) << r.out;     // from the config
  EXPECT_NE(r.out.find("mean of 4 jittered passes"), std::string::npos) << r.out;  // default
  // The model's density and its beta (0.05 at initialisation).
  EXPECT_NE(r.out.find("volsdf density with beta 0.0"), std::string::npos) << r.out;
  for (const char* stem : {"video00_frame00000", "video01_frame00004", "video01_frame00005"}) {
    const cv::Mat png = cv::imread(out + "/frames/" + stem + ".png");
    ASSERT_FALSE(png.empty()) << stem;
    EXPECT_EQ(png.cols, 5 * 48 * 2);
    EXPECT_EQ(png.rows, 48 * 2);
    const cv::Mat err = cv::imread(out + "/errors/" + stem + ".png");
    ASSERT_FALSE(err.empty()) << stem;
    EXPECT_EQ(err.cols, 3 * 48 * 2);
    EXPECT_EQ(err.rows, 48 * 2);
  }
  // Exactly the selected frames.
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(out + "/frames"))
    pngs += e.path().extension() == ".png";
  EXPECT_EQ(pngs, 3);
  EXPECT_TRUE(fs::exists(out + "/turntable/view001.png"));
  std::ifstream csv(out + "/errors.csv");
  std::string header, line;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("video,frame,partner_frame,rgb_error,mask_error,mask_iou,flow_epe", 0), 0u)
      << header;
  int rows = 0;
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, 3);
}

// `banmo solve --holdout-every`: the held-out frames are scored at the end
// (OUT/holdout), the setting is recorded for --resume, and another value
// with --resume is refused by name.
TEST_F(RenderCli, SolveScoresHeldOutFrames) {
  std::ofstream(Path("tiny.yaml")) << kConfig;
  const std::string out = Path("holdout_solve");
  const auto solve = RunBanmo("solve --data " + Data() + " --config " + Path("tiny.yaml") +
                              " --out " + out + " --holdout-every 3 --no-extract --quiet");
  ASSERT_EQ(solve.exit_code, 0) << solve.out;
  EXPECT_NE(solve.out.find("4 frame(s) held out (1 in 3"), std::string::npos) << solve.out;
  EXPECT_NE(solve.out.find("held-out frames (1 in 3, 4 frames): mask IoU"), std::string::npos)
      << solve.out;
  std::ifstream json(out + "/holdout/summary.json");
  const std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"mask_iou\": 0."), std::string::npos) << text;
  EXPECT_NE(text.find("\"psnr\": "), std::string::npos) << text;
  for (const char* stem :
       {"video00_frame00001", "video00_frame00004", "video01_frame00001", "video01_frame00004"}) {
    EXPECT_TRUE(fs::exists(out + "/holdout/frames/" + stem + ".png")) << stem;
  }
  EXPECT_TRUE(fs::exists(out + "/holdout.yaml"));
  const auto again = RunBanmo("solve --data " + Data() + " --config " + Path("tiny.yaml") +
                              " --out " + out + " --resume --holdout-every 2 --no-extract");
  EXPECT_EQ(again.exit_code, 2) << again.out;
  EXPECT_NE(again.out.find("holdout.yaml records the solve's --holdout-every 3"), std::string::npos)
      << again.out;
  const auto bad = RunBanmo("solve --data " + Data() + " --config " + Path("tiny.yaml") +
                            " --out " + Path("holdout_bad") + " --holdout-every 1");
  EXPECT_EQ(bad.exit_code, 2) << bad.out;
  EXPECT_NE(bad.out.find("--holdout-every: expected 0 (none) or an integer >= 2, got 1"),
            std::string::npos)
      << bad.out;
  EXPECT_FALSE(fs::exists(Path("holdout_bad")));
}

TEST_F(RenderCli, DefaultSelectionIsEveryKthFrame) {
  const std::string out = Path("every");
  const auto r = RunBanmo("render --model " + Model() + " --data " + Data() + " --out " + out +
                          " --every 4 --mesh-resolution 0 --scale 1");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  // Frames 0 and 4 of each of the two 6-frame videos.
  for (const char* stem :
       {"video00_frame00000", "video00_frame00004", "video01_frame00000", "video01_frame00004"}) {
    EXPECT_TRUE(fs::exists(out + "/frames/" + stem + ".png")) << stem;
  }
  EXPECT_FALSE(fs::exists(out + "/frames/video00_frame00001.png"));
}

// kill -9 in the middle of a render: OUT does not appear (the frames are in
// a staging folder beside it), and the next render removes that folder and
// writes OUT whole (docs/robustness.md, "Nothing half-written").
TEST_F(RenderCli, AKilledRunLeavesNoPartialFolderAndTheNextRunRecovers) {
  const std::string out = Path("killed");
  const std::string staging_glob = Path(".killed.render.staging-") + "$p";
  // Slow options (every frame, many samples and passes); killed as soon as
  // the first frame is in the staging folder.
  const auto killed = testing::RunShell(
      std::string(BANMO_BINARY) + " render --model " + Model() + " --data " + Data() + " --out " +
      out +
      " --every 1 --samples 64 --jitter-passes 4 --mesh-resolution 0 --scale 1 --threads 1 "
      ">/dev/null 2>&1 & p=$!; for i in $(seq 1 2400); do "
      "ls " +
      staging_glob +
      "/frames/*.png >/dev/null 2>&1 && break; sleep 0.05; done; "
      "kill -9 $p; wait $p; ls -d " +
      staging_glob + " && echo staged");
  ASSERT_NE(killed.out.find("staged"), std::string::npos) << killed.out;
  EXPECT_FALSE(fs::exists(out));
  const auto r = RunBanmo("render --model " + Model() + " --data " + Data() + " --out " + out +
                          " --every 6 --mesh-resolution 0 --scale 1");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("removed the incomplete staging folder"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(out + "/frames/video00_frame00000.png"));
  EXPECT_TRUE(fs::exists(out + "/errors.csv"));
  for (const auto& e : fs::directory_iterator(*root_)) {
    EXPECT_EQ(e.path().filename().string().find(".killed.render.staging"), std::string::npos)
        << e.path();
  }
}

TEST_F(RenderCli, MissingModelIsAnErrorAndWritesNothing) {
  const std::string out = Path("missing_model");
  const auto r = RunBanmo("render --model " + Path("nope") + " --data " + Data() + " --out " + out);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("error: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(Path("nope")), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(RenderCli, DatasetThatDoesNotMatchTheModelIsAnError) {
  // The same scene with 5 frames per video instead of 6.
  Dataset shorter = testing::TinyQuadrupedDataset();
  for (Video& v : shorter.videos) v.frames.pop_back();
  for (Video& v : shorter.videos) {
    for (Frame& f : v.frames) {
      // Drop flow pointing past the new end.
      std::vector<FlowField> kept;
      for (const FlowField& fl : f.flows) {
        if (f.index + fl.gap < static_cast<int>(v.frames.size())) kept.push_back(fl);
      }
      f.flows = kept;
    }
  }
  const std::string data = Path("data_short");
  WriteDataset(shorter, data);
  const std::string out = Path("mismatch");
  const auto r = RunBanmo("render --model " + Model() + " --data " + data + " --out " + out);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find(data + "/video_000: 5 frames, the model's video 0 has 6"), std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(RenderCli, BadFrameSelectionsAreErrors) {
  for (const std::string frames : {"0:99", "7:0", "0:x", "none"}) {
    const std::string out = Path("bad_frames");
    const auto r = RunBanmo("render --model " + Model() + " --data " + Data() + " --out " + out +
                            " --frames " + frames);
    EXPECT_EQ(r.exit_code, 2) << frames << ": " << r.out;
    EXPECT_NE(r.out.find("--frames"), std::string::npos) << frames << ": " << r.out;
    EXPECT_FALSE(fs::exists(out)) << frames;
  }
}

TEST_F(RenderCli, BadOptionsAreErrorsNamingTheFlag) {
  for (const auto& [args, flag] : std::vector<std::pair<std::string, std::string>>{
           {"--every 0", "--every"},
           {"--bounds 1,2,3", "--bounds"},
           {"--bounds 0,0,0,1,x,1", "--bounds"},
           {"--scale -1", "--scale"},
           {"--importance maybe", "--importance"},
           {"--samples -2", "--samples"},
           {"--importance-samples -2", "--importance-samples"},
           {"--min-sdf-sample maybe", "--min-sdf-sample"},
           // The test model was trained without the importance pass.
           {"--min-sdf-sample on", "--min-sdf-sample on: needs the importance pass"},
           {"--jitter-passes -1", "--jitter-passes"}}) {
    const std::string out = Path("bad_option");
    const auto r =
        RunBanmo("render --model " + Model() + " --data " + Data() + " --out " + out + " " + args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.out;
    EXPECT_NE(r.out.find("error: " + flag), std::string::npos) << args << ": " << r.out;
    EXPECT_FALSE(fs::exists(out)) << args;
  }
}

TEST_F(RenderCli, HelpListsTheOptions) {
  const auto r = RunBanmo("render --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* flag : {"--model", "--data", "--out", "--frames", "--every", "--samples",
                           "--importance-samples", "--min-sdf-sample", "--jitter-passes",
                           "--mesh-resolution", "--rgb-error-max", "--video", "--turntable"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
}

}  // namespace
}  // namespace banmo
