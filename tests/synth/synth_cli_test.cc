// `banmo synth` on glTF files as users have them, run as the built binary:
// a Draco-compressed copy of the Fox (made here, never committed) renders
// into a dataset `banmo check` accepts; a file requiring an unknown
// extension is refused with the extension's name; the pose-noise models'
// options and record.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "../common/run_banmo.h"
#include "../common/shared_assets.h"
#include "gltf_files.h"

namespace banmo::synth {
namespace {

using banmo::testing::RunBanmo;

std::string Temp(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/synth_cli_test";
  std::filesystem::create_directories(dir);
  return dir + "/" + name;
}

TEST(SynthCommand, DracoCompressedFoxRendersAndChecks) {
  const std::string fox = banmo::testing::SharedAsset("data/gltf/Fox/Fox.glb");
  ASSERT_TRUE(banmo::testing::SharedAssetExists(fox));
  const std::string draco = Temp("fox_draco.glb");
  testing::WriteGltf(testing::DracoCompressed(testing::ReadPlain(fox), 14), draco);
  const std::string out = Temp("fox_draco_ds");
  std::filesystem::remove_all(out);
  const auto r =
      RunBanmo("synth --rig " + draco +
               " --animation Walk --videos 2 --frames 4 --size 64 --gaps 1 --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto c = RunBanmo("check " + out);
  EXPECT_EQ(c.exit_code, 0) << c.out;
  EXPECT_NE(c.out.find("videos    2\n"), std::string::npos) << c.out;
}

TEST(SynthCommand, UnknownRequiredExtensionIsNamed) {
  tinygltf::Model m = testing::TinyStrip();
  m.extensionsUsed = {"EXT_not_in_this_loader"};
  m.extensionsRequired = {"EXT_not_in_this_loader"};
  const std::string path = Temp("strip_unknown.gltf");
  testing::WriteGltf(m, path);
  const std::string out = Temp("unknown_ds");
  const auto r = RunBanmo("synth --rig " + path + " --videos 1 --frames 2 --size 32 --out " + out);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("EXT_not_in_this_loader"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(path), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(out));
}

// --pose-noise-model: the Gaussian model's record in the printout and in
// root_poses_init.txt, a dataset `banmo check` accepts; an unknown model and
// an unreachable mean are errors naming the flag (exit 2, nothing written).
TEST(SynthCommand, PoseNoiseModel) {
  const std::string out = Temp("gaussian_ds");
  std::filesystem::remove_all(out);
  const auto r = RunBanmo(
      "synth --videos 2 --frames 3 --size 32 --gaps 1 --pose-noise 50 "
      "--pose-noise-model gaussian --out " +
      out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("pose noise 50.0 deg (gaussian)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("rough root poses: gaussian, mean 50 deg (per-axis sigma 31.33"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("root_poses_init vs root_poses_gt over 6 frames: rotation error mean "),
            std::string::npos)
      << r.out;
  std::ifstream in(out + "/video_000/root_poses_init.txt");
  const std::string poses((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(poses.find("# banmo synth pose noise: gaussian"), std::string::npos) << poses;
  EXPECT_NE(poses.find(" 0 0 3\n"), std::string::npos) << poses;  // translation reset
  const auto c = RunBanmo("check " + out);
  EXPECT_EQ(c.exit_code, 0) << c.out;

  const std::string bad = Temp("bad_model_ds");
  std::filesystem::remove_all(bad);
  const auto m = RunBanmo("synth --pose-noise-model gauss --out " + bad);
  EXPECT_EQ(m.exit_code, 2) << m.out;
  EXPECT_NE(m.out.find("--pose-noise-model"), std::string::npos) << m.out;
  EXPECT_NE(m.out.find("{exact, gaussian}"), std::string::npos) << m.out;
  const auto big = RunBanmo("synth --pose-noise-model gaussian --pose-noise 130 --out " + bad);
  EXPECT_EQ(big.exit_code, 2) << big.out;
  EXPECT_NE(big.out.find("--pose-noise: 130 deg"), std::string::npos) << big.out;
  EXPECT_NE(big.out.find("122.55"), std::string::npos) << big.out;
  EXPECT_FALSE(std::filesystem::exists(bad));
}

// --root-offset: the printout says where the object sits in the root frame;
// a malformed or too large offset is an error naming the flag or field
// (exit 2, nothing written).
TEST(SynthCommand, RootOffset) {
  const std::string out = Temp("offset_ds");
  std::filesystem::remove_all(out);
  const auto r = RunBanmo(
      "synth --videos 1 --frames 2 --size 32 --gaps 1 --root-offset 0,-0.8,0.25 --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("object centre at (0, -0.8, 0.25) in the root frame"), std::string::npos)
      << r.out;
  const std::string bad = Temp("bad_offset_ds");
  std::filesystem::remove_all(bad);
  const auto two = RunBanmo("synth --root-offset 1,2 --out " + bad);
  EXPECT_EQ(two.exit_code, 2) << two.out;
  EXPECT_NE(two.out.find("--root-offset '1,2': expected 3 finite numbers"), std::string::npos)
      << two.out;
  const auto word = RunBanmo("synth --root-offset 1,up,2 --out " + bad);
  EXPECT_EQ(word.exit_code, 2) << word.out;
  EXPECT_NE(word.out.find("'up' is not a number"), std::string::npos) << word.out;
  const auto far = RunBanmo("synth --root-offset 0,500,0 --out " + bad);
  EXPECT_EQ(far.exit_code, 2) << far.out;
  EXPECT_NE(far.out.find("root_offset"), std::string::npos) << far.out;
  EXPECT_FALSE(std::filesystem::exists(bad));
}

// --realism casual on the quadruped and the Fox: datasets `banmo check`
// accepts, with the exact masks and true intrinsics as ground truth and no
// features; `banmo prepare` takes their frames and masks; a bad mode and
// pose noise with it are errors naming the flag.
TEST(SynthCommand, RealismCasual) {
  const std::string fox = banmo::testing::SharedAsset("data/gltf/Fox/Fox.glb");
  ASSERT_TRUE(banmo::testing::SharedAssetExists(fox));
  for (const std::string& rig : {std::string("quadruped"), fox}) {
    const std::string out = Temp("casual_ds");
    std::filesystem::remove_all(out);
    const auto r =
        RunBanmo("synth --rig " + rig +
                 " --realism casual --videos 2 --frames 4 --size 48 --gaps 1 --out " + out);
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("realism casual"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("video_001: focal "), std::string::npos) << r.out;
    const auto c = RunBanmo("check " + out);
    EXPECT_EQ(c.exit_code, 0) << c.out;
    EXPECT_NE(c.out.find("present: rgb mask root_poses_init flow depth gt_mesh root_poses_gt "
                         "mask_gt\n"),
              std::string::npos)
        << c.out;
    EXPECT_NE(c.out.find("intrinsics fx 48 fy 48 cx 24 cy 24"), std::string::npos) << c.out;
    EXPECT_NE(c.out.find("true intrinsics (ground truth): fx "), std::string::npos) << c.out;
    EXPECT_FALSE(std::filesystem::exists(out + "/video_000/features"));
    const std::string prepared = Temp("casual_prepared");
    std::filesystem::remove_all(prepared);
    const auto p = RunBanmo("prepare --frames " + out + "/video_000/rgb --masks " + out +
                            "/video_000/mask --gaps 1 --out " + prepared);
    EXPECT_EQ(p.exit_code, 0) << p.out;
    EXPECT_EQ(RunBanmo("check " + prepared).exit_code, 0);
  }
  const std::string bad = Temp("bad_realism_ds");
  std::filesystem::remove_all(bad);
  const auto m = RunBanmo("synth --realism photoreal --out " + bad);
  EXPECT_EQ(m.exit_code, 2) << m.out;
  EXPECT_NE(m.out.find("--realism: unknown mode 'photoreal'"), std::string::npos) << m.out;
  EXPECT_NE(m.out.find("{none, casual}"), std::string::npos) << m.out;
  const auto n = RunBanmo("synth --realism casual --pose-noise 20 --out " + bad);
  EXPECT_EQ(n.exit_code, 2) << n.out;
  EXPECT_NE(n.out.find("--pose-noise"), std::string::npos) << n.out;
  EXPECT_FALSE(std::filesystem::exists(bad));
}

}  // namespace
}  // namespace banmo::synth
