// The solver's divergence guard (issue 66): a learning rate of 1e300 or a
// loss weight of 1e308 (in-process: config files refuse them by key) ends
// with a DivergenceError naming the stage, the batch and what blew up, and
// a checkpoint that resumes; a moderate divergence (lr 1) is reported;
// non-finite near/far planes are an error, not an abort. Configuration
// limits are refused by key. Tiny solves: seconds.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

#include "../common/input_error.h"
#include "../common/run_banmo.h"
#include "banmo/model/make_model.h"
#include "banmo/optim/config.h"
#include "banmo/optim/solver.h"
#include "banmo/util/error.h"
#include "banmo/volume/volume_rendering.h"
#include "tiny_solver_scene.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

std::string Read(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A synthetic dataset (shared by the tests of this file) and a one-stage
// config with `defaults` and `stage` spliced in.
class DivergenceGuard : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One folder per process: ctest runs each test case in its own process,
    // in parallel, and a shared folder would be removed under another.
    dir_ = ::testing::TempDir() + "/divergence_test_" + std::to_string(::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const auto s =
        testing::RunBanmo("synth --videos 1 --frames 4 --size 32 --gaps 1 --out " + dir_ + "/data");
    ASSERT_EQ(s.exit_code, 0) << s.out;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  static testing::CommandResult Solve(const std::string& name, const std::string& defaults,
                                      const std::string& stage, const std::string& extra = "") {
    std::ofstream(dir_ + "/" + name + ".yaml")
        << "model:\n  num_bones: 2\n  field: {sdf_width: 8, color_width: 8, embedding_width: 8}\n"
        << "defaults: {batch_rays: 16, samples_per_ray: 4, sampling: {flow_gaps: [1]}" << defaults
        << "}\nstages: [{name: one, batches: 6" << stage << "}]\n";
    return testing::RunBanmo("solve --data " + dir_ + "/data --config " + dir_ + "/" + name +
                             ".yaml --out " + dir_ + "/" + name + " --no-extract --no-eval " +
                             extra);
  }

  static std::string dir_;
};

std::string DivergenceGuard::dir_;

// The message of the DivergenceError a tiny in-process solve (the config
// bypasses the file checks, as a library caller may) throws; "" if none.
std::string SolveError(const SolverConfig& config, const std::string& out_dir,
                       bool resume = false) {
  const Dataset& data = testing::TinyQuadrupedDataset();
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  SolveOptions options;
  options.quiet = true;
  options.out_dir = out_dir;
  options.resume = resume;
  try {
    solver.Run(options);
  } catch (const DivergenceError& e) {
    return e.what();
  }
  return "";
}

TEST_F(DivergenceGuard, HugeLearningRateStopsWithTheStageBatchAndBlock) {
  SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 6);
  config.stages[0].adam.lr = 1e300;
  const std::string out = dir_ + "/lr";
  fs::remove_all(out);
  const std::string error = SolveError(config, out);
  EXPECT_NE(error.find("the solve diverged in stage 'tiny' (1/1), batch "), std::string::npos)
      << error;
  EXPECT_NE(error.find("left the parameter block '"), std::string::npos) << error;
  EXPECT_NE(error.find("holds the state the run started from"), std::string::npos) << error;
  // The checkpoint is the run's start and resumes (diverging again, cleanly).
  const std::string checkpoint = Read(out + "/checkpoint/checkpoint.yaml");
  EXPECT_NE(checkpoint.find("stage: 0\nbatch: 0\n"), std::string::npos) << checkpoint;
  const std::string resumed = SolveError(config, out, /*resume=*/true);
  EXPECT_NE(resumed.find("holds the last good state"), std::string::npos) << resumed;
}

TEST_F(DivergenceGuard, HugeLossWeightIsNamed) {
  SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 6);
  config.stages[0].losses[LossTerm::kRgb].weight = 1e308;
  const std::string error = SolveError(config, "");
  EXPECT_NE(error.find("the solve diverged in stage 'tiny'"), std::string::npos) << error;
  EXPECT_NE(error.find("losses.rgb.weight 1e+308"), std::string::npos) << error;
  EXPECT_NE(error.find("Nothing was written (no --out)"), std::string::npos) << error;
}

TEST_F(DivergenceGuard, AfterACheckpointTheCheckpointIsTheLastGoodState) {
  // A tame stage (its end writes a checkpoint), then one at lr 1e300.
  SolverConfig config = testing::TinySolverConfig(StepRule::kAdam, 2);
  StageConfig wild = config.stages[0];
  wild.name = "wild";
  wild.batches = 4;
  wild.adam.lr = 1e300;
  config.stages.push_back(wild);
  const std::string out = dir_ + "/two";
  fs::remove_all(out);
  const std::string error = SolveError(config, out);
  EXPECT_NE(error.find("the solve diverged in stage 'wild' (2/2), batch 1/4"), std::string::npos)
      << error;
  EXPECT_NE(error.find("holds the last good state"), std::string::npos) << error;
  const std::string checkpoint = Read(out + "/checkpoint/checkpoint.yaml");
  EXPECT_NE(checkpoint.find("stage: 1\nbatch: 0\n"), std::string::npos) << checkpoint;
}

TEST_F(DivergenceGuard, HugeLearningRateInAConfigFileIsRefusedByKey) {
  const auto r = Solve("lr", ", adam: {lr: 1.0e300}", "");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_EQ(r.out.find("Check failed"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("lr.yaml: stages[0].adam.lr: expected a number in (0, 100]"),
            std::string::npos)
      << r.out;
}

TEST_F(DivergenceGuard, ModerateDivergenceIsReported) {
  const auto r = Solve("moderate", ", adam: {lr: 1.0}, log_every: 1", "");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("the solve may be diverging"), std::string::npos) << r.out;
  // The default learning rate: no warning.
  const auto calm = Solve("calm", "", "");
  EXPECT_EQ(calm.exit_code, 0) << calm.out;
  EXPECT_EQ(calm.out.find("may be diverging"), std::string::npos) << calm.out;
}

// Garbage once accepted silently, each now refused naming the key.
TEST_F(DivergenceGuard, GarbageArgumentsAndCheckpointsAreRefusedByKey) {
  // A flow gap the dataset (gaps [1]) does not have.
  auto r = Solve("gap", "", ", losses: {flow: {weight: 1}}, sampling: {flow_gaps: [1, 8]}");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("stages[0] ('one').sampling.flow_gaps: gap 8 is not in the dataset"),
            std::string::npos)
      << r.out;
  // --threads -5.
  r = Solve("threads", "", "", "--threads -5");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--threads: expected >= 0"), std::string::npos) << r.out;
  // A valid solve, then garbage in its outputs.
  r = Solve("ok", "", "", "--stop-after-batches 2");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::string checkpoint = dir_ + "/ok/checkpoint";
  const std::string yaml = Read(checkpoint + "/checkpoint.yaml");
  // stage 7 of a 1-stage config.
  std::string bad = yaml;
  bad.replace(bad.find("stage: 0"), 8, "stage: 7");
  std::ofstream(checkpoint + "/checkpoint.yaml") << bad;
  r = Solve("ok", "", "", "--resume");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("/checkpoint: stage 7, batch 2 is out of range for the config's 1 stage"),
            std::string::npos)
      << r.out;
  // batch 6 of a 6-batch stage.
  bad = yaml;
  bad.replace(bad.find("batch: 2"), 8, "batch: 6");
  std::ofstream(checkpoint + "/checkpoint.yaml") << bad;
  r = Solve("ok", "", "", "--resume");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("stage 0, batch 6 is out of range"), std::string::npos) << r.out;
  // A state.bin whose length field is absurd, in a checkpoint without the
  // checksum (an older banmo's): an error naming the file, no bad_alloc.
  const std::string state = Read(checkpoint + "/state.bin");
  std::string huge = state;
  for (int k = 28; k < 36; ++k) huge[k] = '\xff';  // the random state's length
  std::ofstream(checkpoint + "/state.bin", std::ios::binary) << huge;
  std::string no_checksum = yaml;
  const std::size_t at = no_checksum.find("state_checksum: ");
  ASSERT_NE(at, std::string::npos) << yaml;
  no_checksum.erase(at, no_checksum.find('\n', at) + 1 - at);
  std::ofstream(checkpoint + "/checkpoint.yaml") << no_checksum;
  r = Solve("ok", "", "", "--resume");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("checkpoint state.bin: truncated or damaged"), std::string::npos) << r.out;
  // With the checksum: the changed bytes are named first.
  std::ofstream(checkpoint + "/checkpoint.yaml") << yaml;
  r = Solve("ok", "", "", "--resume");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("state.bin: checksum"), std::string::npos) << r.out;
  std::ofstream(checkpoint + "/state.bin", std::ios::binary) << state;
  // An unknown key in model.yaml.
  const std::string model = Read(checkpoint + "/model.yaml");
  std::ofstream(checkpoint + "/model.yaml") << model << "surprise: 1\n";
  r = testing::RunBanmo("extract --model " + checkpoint + " --out " + dir_ + "/meshes");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("model.yaml: unknown key 'surprise'"), std::string::npos) << r.out;
  std::ofstream(checkpoint + "/model.yaml") << model;
  // --color-video 99 of a 1-video model.
  r = testing::RunBanmo("extract --model " + checkpoint + " --color-video 99 --out " + dir_ +
                        "/meshes");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--color-video): video 99 does not exist: the model has 1 video(s)"),
            std::string::npos)
      << r.out;
}

// Configuration limits (docs/robustness.md): each refused naming its key.
TEST(ConfigLimits, ValuesBeyondTheLimitsAreRefusedByKey) {
  const std::string head = "stages: [{name: s, batches: 1";
  const struct {
    std::string stage;
    const char* expect;
  } cases[] = {
      {", samples_per_ray: 100000", "stages[0].samples_per_ray: expected an integer in [1, 1024]"},
      {", batch_rays: 100000000", "stages[0].batch_rays: expected an integer in [1, 65536]"},
      {", batch_rays: 65536, samples_per_ray: 1024",
       "stages[0].batch_rays: batch_rays x (samples_per_ray + sampling.importance_samples)"},
      {", adam: {lr: 1.0e300}", "stages[0].adam.lr: expected a number in (0, 100]"},
      {", losses: {rgb: {weight: 1.0e308}}", "stages[0].losses.rgb.weight: expected at most"},
      {", sampling: {eikonal_points: 2000000000}", "stages[0].sampling.eikonal_points"},
  };
  for (const auto& c : cases) {
    const std::string error =
        testing::ErrorOf([&] { ParseSolverConfig(head + c.stage + "}]\n", "limits.yaml"); });
    EXPECT_NE(error.find("limits.yaml"), std::string::npos) << c.stage << ": " << error;
    EXPECT_NE(error.find(c.expect), std::string::npos) << c.stage << ": " << error;
  }
  const std::string bands = testing::ErrorOf([] {
    ParseSolverConfig("model: {field: {position_encoding: {num_bands: 1000}}}\n" +
                          std::string("stages: [{name: s, batches: 1}]\n"),
                      "bands.yaml");
  });
  EXPECT_NE(bands.find("num_bands must be in [0, 32], got 1000"), std::string::npos) << bands;
}

TEST(StratifiedSamples, NonFinitePlanesAreADivergenceErrorNotAnAbort) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(StratifiedSamples(4, inf, inf, 1.0, false, nullptr), DivergenceError);
  EXPECT_THROW(StratifiedSamples(4, 2.0, 1.0, 1.0, false, nullptr), DivergenceError);
  EXPECT_THROW(StratifiedSamples(4, std::nan(""), 1.0, 1.0, false, nullptr), DivergenceError);
  EXPECT_EQ(StratifiedSamples(4, 1.0, 2.0, 1.0, false, nullptr).depths.size(), 4u);
}

}  // namespace
}  // namespace banmo
