// `banmo solve` on bad input: exit status 2, a message naming the file or
// key, and nothing written.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "../common/run_banmo.h"

namespace banmo {
namespace {

std::string Fresh(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/banmo_solve_cli_" + name;
  std::filesystem::remove_all(dir);
  return dir;
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

TEST(SolveCommand, HelpListsTheOptions) {
  const auto r = testing::RunBanmo("solve --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* flag : {"--data", "--config", "--out", "--resume", "--retarget", "--seed"}) {
    EXPECT_NE(r.out.find(flag), std::string::npos) << flag;
  }
}

}  // namespace
}  // namespace banmo
