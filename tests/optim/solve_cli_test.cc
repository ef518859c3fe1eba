// `banmo solve` on bad input: exit status 2, a message naming the file or
// key, and nothing written.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "../common/run_banmo.h"

namespace banmo {
namespace {

std::string Fresh(const std::string& name) {
  // The process id: other test processes (parallel ctest, other build
  // folders) may run the same test at the same time.
  const std::string dir =
      ::testing::TempDir() + "/banmo_solve_cli_" + name + "_" + std::to_string(::getpid());
  std::filesystem::remove_all(dir);
  return dir;
}

// A one-batch solve of dir/data with a tiny model (no extraction) into
// dir/name; `model_keys` are extra lines of the config's `model:` section.
testing::CommandResult SolveOneBatch(const std::string& dir, const std::string& name,
                                     const std::string& model_keys) {
  std::ofstream(dir + "/" + name + ".yaml")
      << "model:\n  num_bones: 2\n  field: {sdf_width: 8, color_width: 8, embedding_width: 8}\n"
      << model_keys
      << "defaults: {batch_rays: 16, samples_per_ray: 4, sampling: {flow_gaps: [1]}}\n"
         "stages: [{name: one, batches: 1}]\n";
  return testing::RunBanmo("solve --data " + dir + "/data --config " + dir + "/" + name +
                           ".yaml --out " + dir + "/" + name + " --no-extract --quiet");
}

// dir/data: a one-video synthetic scene of `frames` 32 px frames; dir/NAME.yaml:
// a tiny model's config of one stage of `batches` batches.
bool WriteTinyScene(const std::string& dir, int frames, const std::string& name, int batches) {
  const auto s = testing::RunBanmo("synth --videos 1 --frames " + std::to_string(frames) +
                                   " --size 32 --gaps 1 --out " + dir + "/data");
  EXPECT_EQ(s.exit_code, 0) << s.out;
  std::ofstream(dir + "/" + name + ".yaml")
      << "model:\n  num_bones: 2\n  field: {sdf_width: 8, color_width: 8, embedding_width: 8}\n"
      << "defaults: {batch_rays: 16, samples_per_ray: 4, sampling: {flow_gaps: [1]}}\n"
      << "stages: [{name: one, batches: " << batches << "}]\n";
  return s.exit_code == 0;
}

TEST(SolveCommand, UnknownConfigKeyIsAnErrorNamingItAndWritesNothing) {
  const std::string dir = Fresh("key");
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/bad.yaml") << "stages:\n  - name: a\n    iteratons: 3\n";
  const auto r = testing::RunBanmo("solve --data " + dir + " --config " + dir + "/bad.yaml --out " +
                                   dir + "/out");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("stages[0].iteratons"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("line 3"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out"));
}

TEST(SolveCommand, MissingDatasetIsAnErrorAndWritesNothing) {
  const std::string dir = Fresh("data");
  const auto r = testing::RunBanmo("solve --data " + dir + "/missing --config " +
                                   std::string(BANMO_SOURCE_DIR) + "/problems/tiny.yaml --out " +
                                   dir + "/out");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find(dir + "/missing"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out"));
}

TEST(SolveCommand, ResumeWithoutCheckpointIsAnError) {
  const std::string dir = Fresh("resume");
  const auto r =
      testing::RunBanmo("solve --data " + dir + " --config " + std::string(BANMO_SOURCE_DIR) +
                        "/problems/tiny.yaml --out " + dir + "/out --resume");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("checkpoint"), std::string::npos) << r.out;
}

// model.root_init_smoothing: `banmo solve` smooths a synthetic dataset's
// noisy root poses before the model is made, says so per video, and reports
// the smoothed poses' error, lower than the rough ones' (a one-batch solve).
TEST(SolveCommand, RootInitSmoothingIsReportedAndLowersThePoseError) {
  const std::string dir = Fresh("smoothing");
  const auto s = testing::RunBanmo(
      "synth --videos 1 --frames 12 --size 32 --gaps 1 --pose-noise 40 --pose-noise-model "
      "gaussian --out " +
      dir + "/data");
  ASSERT_EQ(s.exit_code, 0) << s.out;
  const auto r = SolveOneBatch(dir, "smooth", "  root_init_smoothing: {enabled: true}\n");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("root-pose smoothing (model.root_init_smoothing), video 0: noise "),
            std::string::npos)
      << r.out;
  auto error_after = [&](const std::string& label) {
    const size_t at = r.out.find(label + " root poses: rotation error ");
    EXPECT_NE(at, std::string::npos) << label << "\n" << r.out;
    return at == std::string::npos ? 0.0 : std::stod(r.out.substr(r.out.find("error ", at) + 6));
  };
  const double rough = error_after("initial");
  const double smoothed = error_after("smoothed");
  EXPECT_GT(rough, 25.0);
  EXPECT_LT(smoothed, 0.75 * rough);
}

// model.root_init_registration: a video prepared from frames, masks and
// features without --poses (every root rotation the identity) is registered
// from its features before the solve (a one-batch solve).
TEST(SolveCommand, RootInitRegistrationRegistersAPreparedVideoWithoutPoses) {
  const std::string dir = Fresh("registration");
  const auto s =
      testing::RunBanmo("synth --videos 1 --frames 10 --size 64 --gaps 1 --out " + dir + "/synth");
  ASSERT_EQ(s.exit_code, 0) << s.out;
  const std::string video = dir + "/synth/video_000";
  const auto p =
      testing::RunBanmo("prepare --frames " + video + "/rgb --masks " + video +
                        "/mask --features " + video + "/features --gaps 1 --out " + dir + "/data");
  ASSERT_EQ(p.exit_code, 0) << p.out;
  const auto r = SolveOneBatch(dir, "register", "  root_init_registration: {enabled: true}\n");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("root-pose registration (model.root_init_registration): 10 frame(s) "
                       "registered from 300 reference features"),
            std::string::npos)
      << r.out;
  // Off: the identity poses stay.
  const auto off = SolveOneBatch(dir, "off", "");
  ASSERT_EQ(off.exit_code, 0) << off.out;
  EXPECT_EQ(off.out.find("root-pose registration"), std::string::npos) << off.out;
}

// --stop-after-batches: a 3-batch solve stopped after 2 batches exits 0 with
// a checkpoint at batch 2 and the resume command; --resume finishes it.
TEST(SolveCommand, StopAfterBatchesWritesACheckpointAndResumes) {
  const std::string dir = Fresh("stop");
  ASSERT_TRUE(WriteTinyScene(dir, 4, "three", 3));
  const std::string solve = "solve --data " + dir + "/data --config " + dir + "/three.yaml --out " +
                            dir + "/out --no-extract --no-eval";
  const auto stopped = testing::RunBanmo(solve + " --seed 3 --stop-after-batches 2");
  ASSERT_EQ(stopped.exit_code, 0) << stopped.out;
  EXPECT_NE(stopped.out.find("stopped as asked (--stop-after-batches): resume with"),
            std::string::npos)
      << stopped.out;
  auto read = [](const std::string& path) {
    std::ifstream in(path);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string text = read(dir + "/out/checkpoint/checkpoint.yaml");
  EXPECT_NE(text.find("batch: 2"), std::string::npos) << text;
  // Another seed cannot take effect on a resume (the random state is the
  // checkpoint's): an error naming both, and nothing written.
  const std::string config = read(dir + "/out/config.yaml");
  const auto reseeded = testing::RunBanmo(solve + " --resume --seed 7");
  EXPECT_EQ(reseeded.exit_code, 2) << reseeded.out;
  EXPECT_NE(reseeded.out.find("--seed 7 with --resume"), std::string::npos) << reseeded.out;
  EXPECT_NE(reseeded.out.find("random state of seed 3"), std::string::npos) << reseeded.out;
  EXPECT_EQ(read(dir + "/out/checkpoint/checkpoint.yaml"), text);
  EXPECT_EQ(read(dir + "/out/config.yaml"), config);
  // Without --seed (the resume command printed) the checkpoint's seed goes on.
  const auto resumed = testing::RunBanmo(solve + " --resume");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.out;
  EXPECT_NE(resumed.out.find("1 stage(s)"), std::string::npos) << resumed.out;
  EXPECT_NE(read(dir + "/out/config.yaml").find("\nseed: 3\n"), std::string::npos);
  EXPECT_EQ(testing::RunBanmo(solve + " --resume --stop-after-batches -1").exit_code, 2);
}

TEST(SolveCommand, ResumeBeforeTheFirstCheckpointStartsAgain) {
  // A solve killed before its first checkpoint leaves config.yaml and
  // holdout.yaml (and maybe a partial checkpoint.tmp/): --resume starts it
  // again with the seed and --holdout-every they record, and ends with the
  // parameters of the uninterrupted solve, byte for byte.
  const std::string dir = Fresh("restart");
  ASSERT_TRUE(WriteTinyScene(dir, 6, "two", 2));
  const std::string solve = "solve --data " + dir + "/data --config " + dir + "/two.yaml --out ";
  const std::string flags = " --no-extract --no-eval --holdout-every 3";
  const auto whole = testing::RunBanmo(solve + dir + "/whole --seed 5" + flags);
  ASSERT_EQ(whole.exit_code, 0) << whole.out;
  // What the kill left: the two files of the start and an empty staging folder.
  namespace fs = std::filesystem;
  fs::create_directories(dir + "/killed/checkpoint.tmp");
  fs::copy_file(dir + "/whole/config.yaml", dir + "/killed/config.yaml");
  fs::copy_file(dir + "/whole/holdout.yaml", dir + "/killed/holdout.yaml");
  const auto resumed = testing::RunBanmo(solve + dir + "/killed --no-extract --no-eval --resume");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.out;
  EXPECT_NE(resumed.out.find("has no checkpoint yet"), std::string::npos) << resumed.out;
  EXPECT_NE(resumed.out.find("(seed 5)"), std::string::npos) << resumed.out;
  EXPECT_NE(resumed.out.find("held out (1 in 3"), std::string::npos) << resumed.out;
  auto read = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string params = read(dir + "/whole/checkpoint/params.bin");
  ASSERT_FALSE(params.empty());
  EXPECT_EQ(read(dir + "/killed/checkpoint/params.bin"), params);
  fs::remove_all(dir);
}

TEST(SolveCommand, HelpListsTheOptions) {
  const auto r = testing::RunBanmo("solve --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* flag : {"--data", "--config", "--out", "--resume", "--retarget", "--seed",
                           "--stop-after-batches"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
}

}  // namespace
}  // namespace banmo
