#include "banmo/util/atomic_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

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

}  // namespace
}  // namespace banmo
