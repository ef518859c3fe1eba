// The solver's divergence guard (issue 66): a learning rate of 1e300 or a
// loss weight of 1e308 ends with exit 2, a message naming the stage, the
// batch and what blew up, and a checkpoint that resumes; a moderate
// divergence (lr 1) is reported; non-finite near/far planes are an error,
// not an abort. Tiny solves (16 rays, 4 samples): seconds.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

#include "../common/input_error.h"
#include "../common/run_banmo.h"
#include "banmo/util/error.h"
#include "banmo/volume/volume_rendering.h"

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
    dir_ = ::testing::TempDir() + "/divergence_test";
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const auto s =
        testing::RunBanmo("synth --videos 1 --frames 4 --size 32 --gaps 1 --out " + dir_ + "/data");
    ASSERT_EQ(s.exit_code, 0) << s.out;
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

TEST_F(DivergenceGuard, HugeLearningRateStopsWithTheStageBatchAndBlock) {
  const auto r = Solve("lr", ", adam: {lr: 1.0e300}", "");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_EQ(r.out.find("Check failed"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the solve diverged in stage 'one' (1/1), batch "), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("left the parameter block '"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("holds the state the run started from"), std::string::npos) << r.out;
  // The checkpoint is the run's start and resumes (diverging again, cleanly).
  const std::string checkpoint = Read(dir_ + "/lr/checkpoint/checkpoint.yaml");
  EXPECT_NE(checkpoint.find("stage: 0\nbatch: 0\n"), std::string::npos) << checkpoint;
  const auto resumed = Solve("lr", ", adam: {lr: 1.0e300}", "", "--resume");
  EXPECT_EQ(resumed.exit_code, 2) << resumed.out;
  EXPECT_NE(resumed.out.find("holds the last good state"), std::string::npos) << resumed.out;
}

TEST_F(DivergenceGuard, HugeLossWeightIsNamed) {
  const auto r = Solve("weight", "", ", losses: {rgb: {weight: 1.0e308}}");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("the solve diverged in stage 'one'"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("losses.rgb.weight 1e+308"), std::string::npos) << r.out;
}

TEST_F(DivergenceGuard, AfterACheckpointTheCheckpointIsTheLastGoodState) {
  // A tame stage (its end writes a checkpoint), then one at lr 1e300.
  std::ofstream(dir_ + "/two.yaml")
      << "model:\n  num_bones: 2\n  field: {sdf_width: 8, color_width: 8, embedding_width: 8}\n"
      << "defaults: {batch_rays: 16, samples_per_ray: 4, sampling: {flow_gaps: [1]}}\n"
      << "stages: [{name: tame, batches: 2}, {name: wild, batches: 4, adam: {lr: 1.0e300}}]\n";
  const auto r = testing::RunBanmo("solve --data " + dir_ + "/data --config " + dir_ +
                                   "/two.yaml --out " + dir_ + "/two --no-extract --no-eval");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("the solve diverged in stage 'wild' (2/2), batch 1/4"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("holds the last good state"), std::string::npos) << r.out;
  const std::string checkpoint = Read(dir_ + "/two/checkpoint/checkpoint.yaml");
  EXPECT_NE(checkpoint.find("stage: 1\nbatch: 0\n"), std::string::npos) << checkpoint;
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

TEST(StratifiedSamples, NonFinitePlanesAreADivergenceErrorNotAnAbort) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(StratifiedSamples(4, inf, inf, 1.0, false, nullptr), DivergenceError);
  EXPECT_THROW(StratifiedSamples(4, 2.0, 1.0, 1.0, false, nullptr), DivergenceError);
  EXPECT_THROW(StratifiedSamples(4, std::nan(""), 1.0, 1.0, false, nullptr), DivergenceError);
  EXPECT_EQ(StratifiedSamples(4, 1.0, 2.0, 1.0, false, nullptr).depths.size(), 4u);
}

}  // namespace
}  // namespace banmo
