// `banmo synth` on glTF files as users have them, run as the built binary:
// a Draco-compressed copy of the Fox (made here, never committed) renders
// into a dataset `banmo check` accepts; a file requiring an unknown
// extension is refused with the extension's name.
#include <gtest/gtest.h>

#include <filesystem>
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

}  // namespace
}  // namespace banmo::synth
