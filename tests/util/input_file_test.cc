#include "banmo/util/input_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "../common/input_error.h"
#include "../common/timeout.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;

std::string Temp(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/input_file_test";
  fs::create_directories(dir);
  const std::string path = dir + "/" + name;
  fs::remove_all(path);
  return path;
}

TEST(InputFile, ReadsARegularFile) {
  const std::string path = Temp("hello.txt");
  std::ofstream(path) << "hello";
  EXPECT_EQ(ReadRegularFile(path), "hello");
  EXPECT_NO_THROW(CheckRegularFile(path));
  EXPECT_FALSE(IsSpecialFile(path));
}

TEST(InputFile, MissingFilesAreNamed) {
  const std::string path = Temp("missing.txt");
  const std::string error = testing::ErrorOf([&] { ReadRegularFile(path, 100, " (hint)"); });
  EXPECT_NE(error.find(path + ": cannot open file (No such file or directory) (hint)"),
            std::string::npos)
      << error;
  EXPECT_NE(testing::ErrorOf([&] { CheckRegularFile(path); }).find(path), std::string::npos);
}

TEST(InputFile, FifoIsRefusedWithoutBlocking) {
  const std::string path = Temp("fifo");
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  EXPECT_TRUE(IsSpecialFile(path));
  const auto read = testing::ErrorOfWithTimeout([&] { ReadRegularFile(path); });
  ASSERT_TRUE(read.finished) << "reading a FIFO hung";
  EXPECT_EQ(read.message, path + ": is a FIFO (named pipe), expected a regular file");
  const auto check = testing::ErrorOfWithTimeout([&] { CheckRegularFile(path); });
  ASSERT_TRUE(check.finished);
  EXPECT_EQ(check.message, read.message);
}

TEST(InputFile, DevicesAndFoldersAreRefused) {
  EXPECT_EQ(testing::ErrorOf([] { ReadRegularFile("/dev/zero"); }),
            "/dev/zero: is a character device, expected a regular file");
  const std::string dir = Temp("folder");
  fs::create_directories(dir);
  EXPECT_EQ(testing::ErrorOf([&] { ReadRegularFile(dir); }),
            dir + ": is a directory, expected a regular file");
  // A symbolic link to a device is followed and refused too.
  const std::string link = Temp("zero_link");
  fs::create_symlink("/dev/zero", link);
  EXPECT_NE(testing::ErrorOf([&] { CheckRegularFile(link); }).find("character device"),
            std::string::npos);
}

TEST(InputFile, SymlinkLoopIsNamed) {
  const std::string a = Temp("loop_a"), b = Temp("loop_b");
  fs::create_symlink(b, a);
  fs::create_symlink(a, b);
  const std::string error = testing::ErrorOf([&] { ReadRegularFile(a); });
  EXPECT_NE(error.find(a + ": cannot open file (Too many levels of symbolic links)"),
            std::string::npos)
      << error;
}

TEST(InputFile, SizeLimitIsCheckedBeforeReading) {
  const std::string path = Temp("big.bin");
  std::ofstream(path) << std::string(1000, 'x');
  EXPECT_EQ(ReadRegularFile(path, 1000).size(), 1000u);
  EXPECT_EQ(
      testing::ErrorOf([&] { ReadRegularFile(path, 999); }),
      path + ": file of 1000 bytes is larger than the limit of 999 bytes for this kind of file");
}

}  // namespace
}  // namespace banmo
