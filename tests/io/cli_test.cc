// The `banmo check` and `banmo prepare` commands, run as the built binary:
// exit codes and messages.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>

#include "banmo/io/dataset.h"
#include "banmo/io/prepare.h"
#include "test_dataset_util.h"

namespace banmo {
namespace {

using testing::MakeGtMeshes;
using testing::MakeSmallDataset;
using testing::ReadText;
using testing::TempDir;
using testing::WriteText;

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

RunResult RunBanmo(const TempDir& tmp, const std::string& args) {
  const std::string out = tmp.path() + "/stdout.txt";
  const std::string err = tmp.path() + "/stderr.txt";
  const std::string cmd = std::string(BANMO_BINARY) + " " + args + " > " + out + " 2> " + err;
  const int status = std::system(cmd.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = ReadText(out);
  r.err = ReadText(err);
  return r;
}

TEST(CheckCommand, ValidDatasetPrintsSummary) {
  TempDir tmp;
  Dataset d = MakeSmallDataset();
  d.videos[1].frames[3].mask.setTo(0);
  const auto meshes = MakeGtMeshes(d);
  WriteDataset(d, tmp.path() + "/ds", &meshes);
  const RunResult r = RunBanmo(tmp, "check " + tmp.path() + "/ds");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("videos    2"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("frames    10 (1 skipped"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("flow gaps 1, 2"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("scale     s = "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("centre    ("), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("video video1: 5 frames, 24x20"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("present: rgb mask root_poses_init flow features depth gt_mesh "
                       "root_poses_gt"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("skipped frames: 3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("on disk"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("empty mask"), std::string::npos) << r.err;  // the warning
  EXPECT_EQ(RunBanmo(tmp, "check --quick " + tmp.path() + "/ds").exit_code, 0);
}

TEST(CheckCommand, BadDatasetExitsWithTwoAndNamesTheFile) {
  TempDir tmp;
  WriteDataset(MakeSmallDataset(), tmp.path() + "/ds");
  const std::string path = tmp.path() + "/ds/video0/features/00002.npy";
  const std::string bytes = ReadText(path);
  WriteText(path, bytes.substr(0, bytes.size() - 100));
  const RunResult r = RunBanmo(tmp, "check " + tmp.path() + "/ds");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("error: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("video0/features/00002.npy"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("valid"), std::string::npos) << r.out;
}

TEST(CheckCommand, MissingFolderAndArguments) {
  TempDir tmp;
  const RunResult r = RunBanmo(tmp, "check " + tmp.path() + "/nothing");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("nothing: not a folder"), std::string::npos) << r.err;
  EXPECT_NE(RunBanmo(tmp, "check").exit_code, 0);
  EXPECT_EQ(RunBanmo(tmp, "check --help").exit_code, 0);
}

TEST(PrepareCommand, WritesADatasetThatChecks) {
  TempDir tmp;
  std::filesystem::create_directories(tmp.path() + "/frames");
  std::filesystem::create_directories(tmp.path() + "/masks");
  cv::RNG rng(2);
  for (int t = 0; t < 6; ++t) {
    cv::Mat frame(40, 48, CV_8UC3);
    rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
    cv::imwrite(tmp.path() + "/frames/f" + std::to_string(t) + ".jpg", frame);
    cv::Mat mask(40, 48, CV_8UC1, cv::Scalar(0));
    if (t != 4) mask(cv::Rect(10, 10, 20, 15)).setTo(1);  // 0/1 masks, frame 4 empty
    cv::imwrite(tmp.path() + "/masks/f" + std::to_string(t) + ".png", mask);
  }
  const std::string base = "prepare --frames " + tmp.path() + "/frames --masks " + tmp.path() +
                           "/masks --out " + tmp.path() + "/ds";
  const RunResult r = RunBanmo(tmp, base + " --gaps 1,2,4,8 --intrinsics 50,51,24,20");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("6 frames of 48x40, 1 skipped"), std::string::npos) << r.out;
  const RunResult c = RunBanmo(tmp, "check " + tmp.path() + "/ds");
  EXPECT_EQ(c.exit_code, 0) << c.err;
  EXPECT_NE(c.out.find("intrinsics fx 50 fy 51 cx 24 cy 20"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("present: rgb mask root_poses_init flow\n"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("skipped frames: 4"), std::string::npos) << c.out;
  // The output exists now: refused without --overwrite, nothing changed.
  const RunResult again = RunBanmo(tmp, base + " --gaps 1,2,4,8");
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_NE(again.err.find("not empty"), std::string::npos) << again.err;
  EXPECT_EQ(RunBanmo(tmp, base + " --overwrite --gaps 1").exit_code, 0);
  EXPECT_NE(ReadText(tmp.path() + "/ds/manifest.yaml").find("flow_gaps: [1]"), std::string::npos);
  // --roots-turn-with-camera reports the camera's turn (of noise frames: the
  // line is checked, not the turn; tests/io/camera_motion_test.cc checks
  // turns); without gap 1 it warns and keeps identity rotations.
  const RunResult turned = RunBanmo(tmp, base + " --overwrite --gaps 1 --roots-turn-with-camera");
  EXPECT_EQ(turned.exit_code, 0) << turned.err;
  EXPECT_NE((turned.out + turned.err).find("camera rotation from the background's flow"),
            std::string::npos)
      << turned.out << turned.err;
  const RunResult no_gap_1 = RunBanmo(tmp, base + " --overwrite --gaps 2 --roots-turn-with-camera");
  EXPECT_EQ(no_gap_1.exit_code, 0) << no_gap_1.err;
  EXPECT_NE((no_gap_1.out + no_gap_1.err).find("no flow gap 1"), std::string::npos)
      << no_gap_1.out << no_gap_1.err;
}

TEST(PrepareCommand, BadArguments) {
  TempDir tmp;
  std::filesystem::create_directories(tmp.path() + "/frames");
  const std::string base = "prepare --frames " + tmp.path() + "/frames --masks " + tmp.path() +
                           "/frames --out " + tmp.path() + "/ds";
  RunResult r = RunBanmo(tmp, base + " --gaps 1,0");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("gaps"), std::string::npos) << r.err;
  r = RunBanmo(tmp, base + " --intrinsics 1,2,3");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--intrinsics"), std::string::npos) << r.err;
  r = RunBanmo(tmp, base + " --mask-format fancy");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--mask-format"), std::string::npos) << r.err;
  r = RunBanmo(tmp, base);  // empty frames folder
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("no frame images"), std::string::npos) << r.err;
  r = RunBanmo(tmp, "prepare --masks x --out y");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--video FILE or --frames DIR"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(tmp.path() + "/ds"));
}

// Three videos into one dataset: frames + masks, then a video file
// (Motion-JPEG in AVI, OpenCV's own writer, so no external codec is
// needed), then frames again under a chosen name; `banmo check` accepts it.
TEST(PrepareCommand, AddsVideosToOneDatasetThatChecks) {
  TempDir tmp;
  const std::string p = tmp.path();
  std::filesystem::create_directories(p + "/a/frames");
  std::filesystem::create_directories(p + "/a/masks");
  std::filesystem::create_directories(p + "/b/masks");
  cv::RNG rng(5);
  cv::VideoWriter writer(p + "/b/clip.avi", cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10,
                         cv::Size(48, 40));
  ASSERT_TRUE(writer.isOpened());
  for (int t = 0; t < 5; ++t) {
    cv::Mat frame(40, 48, CV_8UC3);
    rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
    cv::imwrite(p + "/a/frames/" + std::to_string(t) + ".png", frame);
    writer.write(frame);
    cv::Mat mask(40, 48, CV_8UC1, cv::Scalar(0));
    mask(cv::Rect(10, 10, 20, 15)).setTo(255);
    cv::imwrite(p + "/a/masks/" + std::to_string(t) + ".png", mask);
    cv::imwrite(p + "/b/masks/m" + std::to_string(t) + ".png", mask);
  }
  writer.release();
  const std::string ds = p + "/ds";
  RunResult r = RunBanmo(
      tmp, "prepare --frames " + p + "/a/frames --masks " + p + "/a/masks --gaps 1,2 --out " + ds);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("video 'video_000'"), std::string::npos) << r.out;
  r = RunBanmo(tmp,
               "prepare --add --video " + p + "/b/clip.avi --masks " + p + "/b/masks --out " + ds);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("added to " + ds + ": video 'video_001', 5 frames of 48x40"),
            std::string::npos)
      << r.out;
  const std::string add_a = "prepare --add --frames " + p + "/a/frames --masks " + p +
                            "/a/masks --out " + ds + " --name cat_walk";
  r = RunBanmo(tmp, add_a);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("now has 3 videos"), std::string::npos) << r.out;
  const RunResult c = RunBanmo(tmp, "check " + ds);
  ASSERT_EQ(c.exit_code, 0) << c.err;
  EXPECT_NE(c.out.find("videos    3\n"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("video video_001: 5 frames, 48x40"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("video cat_walk: 5 frames"), std::string::npos) << c.out;
  // Prepared without --features and --poses: noted, not an error.
  EXPECT_NE(c.out.find("note: video video_001 has no pixel features"), std::string::npos) << c.out;
  EXPECT_NE(c.out.find("note: video cat_walk: every initial root pose has the same rotation"),
            std::string::npos)
      << c.out;
  const std::string manifest = ReadText(ds + "/manifest.yaml");

  // Errors: a clashing name, other gaps, no dataset, --add with --overwrite.
  r = RunBanmo(tmp, add_a);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("already has a video named 'cat_walk'"), std::string::npos) << r.err;
  r = RunBanmo(tmp, add_a + "2 --gaps 1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("flow gaps are [1,2], the added video has [1]"), std::string::npos) << r.err;
  r = RunBanmo(tmp, "prepare --add --frames " + p + "/a/frames --masks " + p + "/a/masks --out " +
                        p + "/nothing");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("nothing: not a folder"), std::string::npos) << r.err;
  EXPECT_NE(RunBanmo(tmp, add_a + "3 --overwrite").exit_code, 0);
  EXPECT_EQ(ReadText(ds + "/manifest.yaml"), manifest);
  EXPECT_EQ(RunBanmo(tmp, "check " + ds).exit_code, 0);
}

}  // namespace
}  // namespace banmo

namespace banmo {
namespace {

// `banmo prepare` (library call) on a sequence rendered by `banmo synth`:
// DIS flow against the renderer's exact flow, in pixels the renderer marks
// visible in both frames.
TEST(PrepareOnSynth, RecoversRenderedFlow) {
  TempDir tmp;
  const std::string syn = tmp.path() + "/syn";
  const RunResult r = RunBanmo(tmp,
                               "synth --rig quadruped --videos 1 --frames 12 --size 256 "
                               "--gaps 1,4 --seed 3 --out " +
                                   syn);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Dataset gt = LoadDataset(syn);
  ASSERT_EQ(gt.videos.size(), 1u);
  PrepareOptions options;
  options.frames_dir = syn + "/" + gt.videos[0].name + "/rgb";
  options.masks_dir = syn + "/" + gt.videos[0].name + "/mask";
  options.mask_format = MaskFormat::kBinary;
  options.gaps = {1, 4};
  const Dataset d = PrepareDataset(options);
  ASSERT_EQ(d.videos[0].frames.size(), gt.videos[0].frames.size());
  // Per gap: EPE over pixels the renderer marks visible in both frames, the
  // mean rendered flow magnitude there (= EPE of a zero flow), and the EPE
  // over those pixels that the forward-backward check also keeps.
  for (int gap : {1, 4}) {
    for (int sign : {1, -1}) {
      double sum_epe = 0, sum_mag = 0, sum_kept = 0;
      long n = 0, n_kept = 0;
      for (std::size_t t = 0; t < gt.videos[0].frames.size(); ++t) {
        const FlowField* g = gt.videos[0].frames[t].FlowForGap(sign * gap);
        const FlowField* p = d.videos[0].frames[t].FlowForGap(sign * gap);
        ASSERT_EQ(g == nullptr, p == nullptr);
        if (g == nullptr) continue;
        cv::Mat gf, pf;
        g->flow.convertTo(gf, CV_32F);
        p->flow.convertTo(pf, CV_32F);
        for (int y = 0; y < gf.rows; ++y) {
          for (int x = 0; x < gf.cols; ++x) {
            if (!g->valid.at<unsigned char>(y, x)) continue;
            const cv::Vec2f e = gf.at<cv::Vec2f>(y, x) - pf.at<cv::Vec2f>(y, x);
            const double epe = std::hypot(e[0], e[1]);
            sum_epe += epe;
            sum_mag += cv::norm(gf.at<cv::Vec2f>(y, x));
            ++n;
            if (p->valid.at<unsigned char>(y, x)) {
              sum_kept += epe;
              ++n_kept;
            }
          }
        }
      }
      ASSERT_GT(n, 0);
      const double epe = sum_epe / n;
      const double magnitude = sum_mag / n;
      const double epe_kept = sum_kept / std::max(1L, n_kept);
      std::printf(
          "synth quadruped 256x256, gap %+d: DIS EPE %.2f px over %ld visible pixels (mean "
          "rendered flow %.2f px); forward-backward check keeps %.0f %% of them, EPE there "
          "%.2f px\n",
          sign * gap, epe, n, magnitude, 100.0 * n_kept / n, epe_kept);
      if (gap == 1) {
        // Measured: EPE 2.7-3.3 px for 9.4 px of mean motion (ratio 0.29-0.35):
        // the smooth, shaded colours of the rendered creature leave DIS an
        // aperture problem (its warp matches the colours about as well as
        // the exact flow does). Bound: ratio 0.5, i.e. 1.5x the measurement
        // and half the error of a zero flow.
        EXPECT_LT(epe, 0.5 * magnitude) << "gap " << sign * gap;
      }
      // Gap 4 (about 25 px of articulated motion): DIS fails on this
      // sequence (measured EPE 28-32 px, no better than a zero flow); the
      // numbers are printed and reported in docs/dataset.md, not asserted.
    }
  }
}

}  // namespace
}  // namespace banmo
