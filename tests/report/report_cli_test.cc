// `banmo report` and the exports end to end, with the built binary: the
// report of a tiny solve opened in headless Chromium (the viewer draws, the
// page logs nothing but the viewer's own line, a later animation time gives
// another picture), and the Khronos glTF validator (npm gltf-validator,
// tools/node) on `banmo export` of tiny solves of the quadruped (8, 2 and 0
// bones), the Fox and a Draco-compressed Fox (and on that Draco file
// itself, which may have infos: the validator cannot look into Draco).
// docs/report.md.
//
// BANMO_REPORT_SCREENSHOT=<png> also writes a screenshot of the page's top
// there (docs/report.png is made so).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "banmo/report/report.h"
#include "common/run_banmo.h"
#include "common/shared_assets.h"
#include "synth/gltf_files.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using banmo::testing::CommandResult;
using banmo::testing::RunBanmo;

std::string Temp(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/report_cli_test";
  fs::create_directories(dir);
  return dir + "/" + name;
}

// A shell command, stdout and stderr merged.
CommandResult RunShell(const std::string& command) {
  CommandResult result;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.out.append(buffer, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// RUN/data (synth: 2 videos x 8 frames of 64 px) and RUN/solve
// (problems/tiny.yaml, about 5 s of solving); `rig` is synth's --rig and
// friends. Returns RUN.
std::string TinyRun(const std::string& name, const std::string& rig) {
  const std::string run = Temp(name);
  fs::remove_all(run);
  const CommandResult s = RunBanmo(
      "synth " + rig + " --videos 2 --frames 8 --size 64 --gaps 1,2 --out " + run + "/data");
  EXPECT_EQ(s.exit_code, 0) << s.out;
  const CommandResult r =
      RunBanmo("solve --data " + run + "/data --config " + std::string(BANMO_SOURCE_DIR) +
               "/problems/tiny.yaml --resolution 64 --quiet --out " + run + "/solve");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return run;
}

// Console lines Chromium printed (--enable-logging=stderr): every message the
// page logged, whatever its level, and uncaught exceptions and failed loads.
std::vector<std::string> ConsoleLines(const std::string& log) {
  std::vector<std::string> lines;
  std::istringstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (line.find(":CONSOLE") != std::string::npos) lines.push_back(line);
  }
  return lines;
}

struct Shot {
  cv::Mat image;
  std::vector<std::string> console;
  std::string log;
};

// Opens `url` in headless Chromium (software WebGL: SwiftShader) and
// returns its screenshot and console lines.
Shot Screenshot(const std::string& url, const std::string& png, int width, int height) {
  fs::remove(png);
  const std::string log = png + ".log";
  std::ostringstream cmd;
  cmd << "timeout 180 chromium --headless --disable-gpu --no-sandbox --enable-logging=stderr "
         "--v=0 --use-angle=swiftshader --enable-unsafe-swiftshader --hide-scrollbars "
         "--window-size="
      << width << "," << height << " --virtual-time-budget=10000 --screenshot=" << png << " '"
      << url << "' > " << log << " 2>&1";
  const CommandResult r = RunShell(cmd.str());
  Shot shot;
  shot.log = ReadText(log);
  EXPECT_EQ(r.exit_code, 0) << cmd.str() << "\n" << shot.log;
  shot.console = ConsoleLines(shot.log);
  shot.image = cv::imread(png, cv::IMREAD_COLOR);
  return shot;
}

// The page's console: only the viewer's "drew" line, and SwiftShader's
// performance notes about reading pixels back for the screenshot.
void ExpectCleanConsole(const Shot& shot) {
  bool drew = false;
  for (const std::string& line : shot.console) {
    if (line.find("\"banmo viewer: drew ") != std::string::npos) {
      drew = true;
      continue;
    }
    if (line.find("GL Driver Message (OpenGL, Performance") != std::string::npos) continue;
    ADD_FAILURE() << "console: " << line;
  }
  EXPECT_TRUE(drew) << "the viewer never drew:\n" << shot.log;
}

// Fraction of pixels unlike the viewer's background (#1e232a) by more than
// 24 levels in some channel.
double ObjectFraction(const cv::Mat& bgr) {
  int count = 0;
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(y, x);
      if (std::abs(p[0] - 0x2a) > 24 || std::abs(p[1] - 0x23) > 24 || std::abs(p[2] - 0x1e) > 24) {
        ++count;
      }
    }
  }
  return static_cast<double>(count) / (bgr.rows * bgr.cols);
}

TEST(ReportCommand, TinyRunOpensInChromiumAndAnimates) {
  const std::string run = TinyRun("quadruped", "--rig quadruped");
  const std::string args = " --frames-per-video 1 --turntable 4 --jitter-passes 1";
  const CommandResult r = RunBanmo("report --run " + run + args);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  for (const char* line :
       {"export: model.glb", "render: 2 frames (1 per video)", "[2/2] video 1 frame 0",
        "skipped: held-out mask IoU and PSNR: no holdout/summary.json", "wrote "}) {
    EXPECT_NE(r.out.find(line), std::string::npos) << line << "\n" << r.out;
  }
  // Held-out frames (banmo solve --holdout-every): shown when present.
  fs::create_directories(run + "/solve/holdout");
  std::ofstream(run + "/solve/holdout/summary.json") << "{\"mask_iou\": 0.8125, \"psnr\": 21.5}\n";
  std::ofstream(run + "/solve/holdout/frames.csv")
      << "video,frame,mask_iou,psnr\n0,3,0.75,20.5\n1,5,0.875,22.5\n";
  const CommandResult h = RunBanmo("report --run " + run + args);
  ASSERT_EQ(h.exit_code, 0) << h.out;
  EXPECT_EQ(h.out.find("skipped: held-out"), std::string::npos) << h.out;
  const std::string report = run + "/report";
  for (const char* file :
       {"index.html", "style.css", "viewer.js", "model.js", "model.glb", "three/three.min.js",
        "three/GLTFLoader.js", "three/OrbitControls.js", "render/frames/video00_frame00000.png",
        "render/errors/video01_frame00000.png", "render/turntable/view003.png",
        "render/errors.csv"}) {
    EXPECT_TRUE(fs::exists(report + "/" + file)) << file;
  }
  EXPECT_FALSE(fs::exists(run + "/report.tmp"));
  const std::string html = ReadText(report + "/index.html");
  for (const char* text :
       {"Chamfer distance per frame", "mask IoU of the rendered frames",
        "root-pose rotation error per frame", "stage all", "stage detail", "<td>adam</td>", "F@2%",
        "video 1 frame 0: mask IoU", "src=\"render/errors/video01_frame00000.png\"",
        "<th>mask_iou</th><th>psnr</th>", "0.8125", "held-out frames: psnr"}) {
    EXPECT_NE(html.find(text), std::string::npos) << text;
  }
  for (const char* remote : {"http:", "https:", "//cdn", "import "}) {
    EXPECT_EQ(html.find(remote), std::string::npos)
        << remote << ": the page must not need the network";
  }

  const std::string url = "file://" + fs::absolute(report).string() + "/index.html";
  const Shot first = Screenshot(url + "?shot=1&t=0", Temp("shot_t0.png"), 480, 360);
  const Shot later = Screenshot(url + "?shot=1&t=0.6", Temp("shot_t06.png"), 480, 360);
  ASSERT_FALSE(first.image.empty()) << first.log;
  ASSERT_FALSE(later.image.empty()) << later.log;
  ExpectCleanConsole(first);
  ExpectCleanConsole(later);
  // Not blank: the model covers a good part of the canvas.
  const double covered0 = ObjectFraction(first.image), covered1 = ObjectFraction(later.image);
  EXPECT_GT(covered0, 0.03);
  EXPECT_GT(covered1, 0.03);
  cv::Scalar mean, stddev;
  cv::meanStdDev(first.image, mean, stddev);
  EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 15.0);
  // Animated: another pose at t = 0.6 s.
  cv::Mat diff;
  cv::absdiff(first.image, later.image, diff);
  cv::Mat gray;
  cv::transform(diff, gray, cv::Matx13f(1, 1, 1));
  const double changed = cv::countNonZero(gray > 30) / static_cast<double>(gray.total());
  EXPECT_GT(changed, 0.01);
  std::printf(
      "screenshots: model covers %.3f / %.3f of the canvas, %.3f of the pixels change "
      "from t = 0 to t = 0.6 s\n",
      covered0, covered1, changed);
  // The bones and weight colours drawn too (no console error).
  const Shot toggles =
      Screenshot(url + "?shot=1&t=0.3&bones=1&weights=1", Temp("shot_bones.png"), 480, 360);
  ExpectCleanConsole(toggles);
  if (const char* out = std::getenv("BANMO_REPORT_SCREENSHOT")) {
    const Shot page = Screenshot(url + "?t=0.3&weights=1&bones=1", out, 900, 760);
    ExpectCleanConsole(page);
  }
}

// banmo solve's losses.csv and stages.csv, also across --stop-after-batches
// and --resume: every batch once, in order; the stages' batches add up.
TEST(SolveLog, LossesAndStagesSurviveAResume) {
  const std::string run = TinyRun("resumed", "--rig quadruped");
  const std::string config = std::string(BANMO_SOURCE_DIR) + "/problems/tiny.yaml";
  const CsvTable whole = ReadCsv(run + "/solve/losses.csv");
  ASSERT_TRUE(whole.exists);
  ASSERT_GE(whole.header.size(), 7u);
  EXPECT_EQ(whole.header[0], "stage");
  EXPECT_EQ(whole.header[4], "seconds");
  EXPECT_EQ(whole.header.back(), "total");
  EXPECT_EQ(whole.rows.size(), 300u);  // 200 + 40 + 60 batches of problems/tiny.yaml
  const std::string out = run + "/solve_pieces";
  const std::string solve =
      "solve --data " + run + "/data --config " + config + " --quiet --no-extract --out " + out;
  const CommandResult a = RunBanmo(solve + " --stop-after-batches 150");
  ASSERT_EQ(a.exit_code, 0) << a.out;
  EXPECT_EQ(ReadCsv(out + "/losses.csv").rows.size(), 150u);
  const CommandResult b = RunBanmo(solve + " --resume");
  ASSERT_EQ(b.exit_code, 0) << b.out;
  const CsvTable pieces = ReadCsv(out + "/losses.csv");
  ASSERT_EQ(pieces.rows.size(), 300u);
  const int total = pieces.Column("total_batch");
  for (size_t r = 0; r < pieces.rows.size(); ++r) {
    ASSERT_EQ(pieces.Number(r, total), static_cast<double>(r + 1)) << "row " << r;
  }
  // The same losses as the uninterrupted solve (a resume repeats it).
  const int rgb = pieces.Column("rgb");
  EXPECT_EQ(pieces.rows[299][rgb], whole.rows[299][whole.Column("rgb")]);
  const CsvTable stages = ReadCsv(out + "/stages.csv");
  ASSERT_EQ(stages.rows.size(), 3u);
  const int batches = stages.Column("batches");
  EXPECT_EQ(stages.Number(0, batches), 200.0);
  EXPECT_EQ(stages.Number(1, batches), 40.0);
  EXPECT_EQ(stages.Number(2, batches), 60.0);
  EXPECT_GT(stages.Number(0, stages.Column("rays_per_second")), 0.0);
}

TEST(ReportCommand, MissingRunIsAnErrorAndWritesNothing) {
  const std::string run = Temp("no_run");
  fs::remove_all(run);
  fs::create_directories(run);
  const CommandResult r = RunBanmo("report --run " + run);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--run '" + run + "': no checkpoint/model.yaml"), std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(run + "/report"));
  const CommandResult bad = RunBanmo("report --run " + run + " --frames-per-video -1");
  EXPECT_EQ(bad.exit_code, 2) << bad.out;
  EXPECT_NE(bad.out.find("--frames-per-video"), std::string::npos) << bad.out;
}

// The Khronos validator on the exports: 0 errors and 0 warnings.
TEST(KhronosValidator, ExportsHaveNoErrorsOrWarnings) {
  const std::string node_dir = std::string(BANMO_SOURCE_DIR) + "/tools/node";
  ASSERT_TRUE(fs::exists(node_dir + "/node_modules/gltf-validator/package.json"))
      << "gltf-validator is not installed: run `npm ci` in " << node_dir
      << " (tools/install_deps.sh does)";
  const std::string fox = banmo::testing::SharedAsset("data/gltf/Fox/Fox.glb");
  ASSERT_TRUE(banmo::testing::SharedAssetExists(fox));
  const std::string draco = Temp("fox_draco.glb");
  synth::testing::WriteGltf(synth::testing::DracoCompressed(synth::testing::ReadPlain(fox), 14),
                            draco);
  std::vector<std::string> files = {draco};
  const std::vector<std::pair<std::string, std::string>> runs = {
      {"quadruped_v", "--rig quadruped"},
      {"fox", "--rig " + fox + " --animation Walk"},
      {"fox_draco", "--rig " + draco + " --animation Walk"}};
  for (const auto& [name, rig] : runs) {
    const std::string run = TinyRun(name, rig);
    for (const char* ext : {".glb", ".gltf"}) {
      const std::string out = Temp(name + "_export" + ext);
      const CommandResult e = RunBanmo("export --model " + run + "/solve/checkpoint --out " + out);
      ASSERT_EQ(e.exit_code, 0) << e.out;
      files.push_back(out);
    }
  }
  // Models with 2 bones (spare influence slots: joint 0, weight 0) and
  // none (rigid, no skin), on the quadruped's data.
  const std::string tiny = ReadText(std::string(BANMO_SOURCE_DIR) + "/problems/tiny.yaml");
  ASSERT_NE(tiny.find("num_bones: 8"), std::string::npos);
  for (const int bones : {2, 0}) {
    std::string config = tiny;
    config.replace(config.find("num_bones: 8"), 12, "num_bones: " + std::to_string(bones));
    const std::string name = "bones" + std::to_string(bones);
    std::ofstream(Temp(name + ".yaml")) << config;
    const CommandResult r =
        RunBanmo("solve --data " + Temp("quadruped_v") + "/data --config " + Temp(name + ".yaml") +
                 " --quiet --no-extract --overwrite " + "--out " + Temp(name));
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const std::string out = Temp(name + "_export.glb");
    const CommandResult e = RunBanmo("export --model " + Temp(name) + "/checkpoint --out " + out);
    ASSERT_EQ(e.exit_code, 0) << e.out;
    files.push_back(out);
  }
  std::string args;
  for (const std::string& f : files) args += " " + f;
  const CommandResult v = RunShell("node " + node_dir + "/validate_gltf.js" + args);
  std::printf("%s", v.out.c_str());
  EXPECT_EQ(v.exit_code, 0) << v.out;
  for (const std::string& f : files) {
    EXPECT_NE(v.out.find(f + ": 0 errors, 0 warnings"), std::string::npos) << f << "\n" << v.out;
  }
}

}  // namespace
}  // namespace banmo
