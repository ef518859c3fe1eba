#include "banmo/util/atomic_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "banmo/util/error.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / name;
  fs::remove_all(dir);
  return dir;
}

TEST(WriteFileAtomic, WritesAndReplacesLeavingNoTemporaryFile) {
  const fs::path dir = FreshDir("banmo_atomic_file_test");
  MakeDirectories((dir / "a" / "b").string());
  const fs::path file = dir / "a" / "b" / "x.bin";
  const std::string binary("one\0two", 7);
  WriteFileAtomic(file.string(), binary);
  EXPECT_EQ(ReadText(file), binary);
  WriteFileAtomic(file.string(), "second");
  EXPECT_EQ(ReadText(file), "second");
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(file.parent_path())) {
    (void)entry;
    ++entries;
  }
  EXPECT_EQ(entries, 1);  // no temporary file left beside the target
}

TEST(WriteFileAtomic, UnwritableFolderIsAnErrorNamingThePath) {
  const fs::path dir = FreshDir("banmo_atomic_file_missing");
  const std::string path = (dir / "no_such_folder" / "x.txt").string();
  try {
    WriteFileAtomic(path, "x");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(WriteFileAtomicWith, AFailingWriterLeavesTheTargetUntouched) {
  const fs::path dir = FreshDir("banmo_atomic_file_with");
  MakeDirectories(dir.string());
  const fs::path file = dir / "x.txt";
  WriteFileAtomic(file.string(), "old");
  EXPECT_THROW(WriteFileAtomicWith(file.string(),
                                   [](const std::string& temp) {
                                     std::ofstream(temp) << "half";
                                     return false;
                                   }),
               InputError);
  EXPECT_EQ(ReadText(file), "old");
  EXPECT_THROW(WriteFileAtomicWith(file.string(),
                                   [](const std::string& temp) -> bool {
                                     std::ofstream(temp) << "half";
                                     throw std::runtime_error("writer failed");
                                   }),
               std::exception);
  EXPECT_EQ(ReadText(file), "old");
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    (void)entry;
    ++entries;
  }
  EXPECT_EQ(entries, 1);  // the temporary files were removed
  WriteFileAtomicWith(file.string(), [](const std::string& temp) {
    std::ofstream(temp) << "new";
    return true;
  });
  EXPECT_EQ(ReadText(file), "new");
}

TEST(MakeDirectories, ExistingFolderIsFineAFileInTheWayIsAnError) {
  const fs::path dir = FreshDir("banmo_make_directories");
  MakeDirectories(dir.string());
  MakeDirectories(dir.string());
  EXPECT_TRUE(fs::is_directory(dir));
  WriteFileAtomic((dir / "file").string(), "x");
  EXPECT_THROW(MakeDirectories((dir / "file" / "sub").string()), InputError);
}

// Every entry under `dir`, relative, sorted.
std::vector<std::string> Tree(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    out.push_back(fs::relative(e.path(), dir).string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// A pid no process has (above any pid_max): the files of a "killed run".
const char* kDeadPid = "999999999";

TEST(StagedOutput, ANewFolderAppearsWholeAtCommit) {
  const fs::path root = FreshDir("banmo_staged_new");
  MakeDirectories(root.string());
  const fs::path out = root / "out";
  {
    StagedOutput staged(out.string(), "render");
    EXPECT_FALSE(fs::exists(out));  // staged beside, not inside
    EXPECT_EQ(fs::path(staged.path()).parent_path(), root);
    MakeDirectories(staged.path() + "/frames");
    WriteFileAtomic(staged.path() + "/frames/a.png", "a");
    WriteFileAtomic(staged.path() + "/errors.csv", "e");
    EXPECT_EQ(staged.FinalPath(staged.path() + "/frames/a.png"), (out / "frames/a.png").string());
    EXPECT_FALSE(fs::exists(out));
    staged.Commit();
  }
  EXPECT_EQ(Tree(root),
            (std::vector<std::string>{"out", "out/errors.csv", "out/frames", "out/frames/a.png"}));
}

TEST(StagedOutput, AFailedRunLeavesNothing) {
  const fs::path root = FreshDir("banmo_staged_failed");
  MakeDirectories((root / "old").string());
  WriteFileAtomic((root / "old" / "keep.txt").string(), "k");
  for (const char* name : {"new", "old"}) {
    StagedOutput staged((root / name).string(), "eval");
    WriteFileAtomic(staged.path() + "/summary.json", "half");
    // No Commit: an exception unwinds past it.
  }
  EXPECT_EQ(Tree(root), (std::vector<std::string>{"old", "old/keep.txt"}));
}

TEST(StagedOutput, AnExistingFolderKeepsItsOtherFilesAndGetsTheNewOnes) {
  const fs::path out = FreshDir("banmo_staged_merge");
  MakeDirectories((out / "frames").string());
  WriteFileAtomic((out / "frames" / "a.png").string(), "old a");
  WriteFileAtomic((out / "frames" / "b.png").string(), "old b");
  {
    StagedOutput staged(out.string() + "/", "render");
    EXPECT_EQ(fs::path(staged.path()).parent_path(), out);
    MakeDirectories(staged.path() + "/frames");
    WriteFileAtomic(staged.path() + "/frames/a.png", "new a");
    EXPECT_EQ(ReadText(out / "frames" / "a.png"), "old a");
    staged.Commit();
  }
  EXPECT_EQ(Tree(out), (std::vector<std::string>{"frames", "frames/a.png", "frames/b.png"}));
  EXPECT_EQ(ReadText(out / "frames" / "a.png"), "new a");
  EXPECT_EQ(ReadText(out / "frames" / "b.png"), "old b");
}

// What kill -9 leaves, recovered by the next run: an incomplete staging
// folder (beside or inside) is removed, temporary files of a dead process
// too; a complete one (killed during Commit's moves) is moved in first.
TEST(StagedOutput, TheNextRunRecoversWhatAKilledRunLeft) {
  const fs::path root = FreshDir("banmo_staged_killed");
  const fs::path out = root / "out";
  const std::string dead = kDeadPid;
  MakeDirectories((root / (".out.render.staging-" + dead) / "frames").string());
  WriteFileAtomic((root / (".out.render.staging-" + dead) / "frames" / "x.png").string(), "x");
  {
    StagedOutput staged(out.string(), "render");
    EXPECT_NE(staged.recovery_note().find("removed the incomplete staging folder"),
              std::string::npos)
        << staged.recovery_note();
    WriteFileAtomic(staged.path() + "/errors.csv", "e");
    staged.Commit();
  }
  EXPECT_EQ(Tree(root), (std::vector<std::string>{"out", "out/errors.csv"}));

  // Killed during Commit into an existing folder: a.png moved, b.png not.
  const fs::path complete = out / (".render.staging-" + dead);
  MakeDirectories((complete / "frames").string());
  WriteFileAtomic((complete / ".complete").string(), "");
  WriteFileAtomic((complete / "frames" / "b.png").string(), "killed run's b");
  MakeDirectories((out / "frames").string());
  WriteFileAtomic((out / "frames" / "a.png").string(), "killed run's a");
  WriteFileAtomic((out / "frames" / ("c.png.tmp." + dead + ".7")).string(), "half");
  WriteFileAtomic((out / ("errors.csv.tmp." + dead + ".8")).string(), "half");
  // Not ours: another command's staging, a live process's temporary file.
  MakeDirectories((out / (".eval.staging-" + dead)).string());
  const std::string live = "errors.csv.tmp." + std::to_string(::getpid()) + ".9";
  WriteFileAtomic((out / live).string(), "in progress");
  {
    StagedOutput staged(out.string(), "render");
    EXPECT_NE(staged.recovery_note().find("moved in the complete outputs"), std::string::npos)
        << staged.recovery_note();
    EXPECT_EQ(ReadText(out / "frames" / "b.png"), "killed run's b");
    MakeDirectories(staged.path() + "/frames");
    WriteFileAtomic(staged.path() + "/frames/a.png", "new a");
    staged.Commit();
  }
  EXPECT_EQ(Tree(out), (std::vector<std::string>{".eval.staging-" + dead, "errors.csv", live,
                                                 "frames", "frames/a.png", "frames/b.png"}));
  EXPECT_EQ(ReadText(out / "frames" / "a.png"), "new a");
}

TEST(RemoveStaleTempFilesOf, RemovesOnlyThatFilesTemporariesOfDeadProcesses) {
  const fs::path dir = FreshDir("banmo_stale_of");
  MakeDirectories(dir.string());
  const std::string dead = kDeadPid;
  const std::string live = std::to_string(::getpid());
  for (const std::string& name :
       {std::string("m.glb"), "m.glb.tmp." + dead + ".1", "m.glb.tmp." + live + ".2",
        "other.glb.tmp." + dead + ".3", std::string("m.glb.tmp.x.4")}) {
    WriteFileAtomic((dir / name).string(), "");
  }
  EXPECT_EQ(RemoveStaleTempFilesOf((dir / "m.glb").string()), 1);
  EXPECT_EQ(Tree(dir), (std::vector<std::string>{"m.glb", "m.glb.tmp." + live + ".2",
                                                 "m.glb.tmp.x.4", "other.glb.tmp." + dead + ".3"}));
  EXPECT_TRUE(ProcessMayBeAlive(::getpid()));
  EXPECT_FALSE(ProcessMayBeAlive(999999999));
  EXPECT_FALSE(ProcessMayBeAlive(0));
}

}  // namespace
}  // namespace banmo
