// Datasets made to break the reader (issue 66): FIFOs and devices where
// files belong (refused by name, without blocking), duplicate keys and
// absurd values in manifest.yaml, sizes beyond the documented limits.
// Loads that could block run in a child process with a time limit.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "../common/timeout.h"
#include "banmo/geometry/mesh_io.h"
#include "banmo/io/codecs.h"
#include "banmo/io/dataset.h"
#include "banmo/util/error.h"
#include "test_dataset_util.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing::LoadAll;
using testing::MakeGtMeshes;
using testing::MakeSmallDataset;
using testing::ReadText;
using testing::TempDir;
using testing::WriteText;
using testing::WriteValid;

// The message of LoadDataset(dir)'s InputError, run with a time limit.
std::string TimedLoadError(const std::string& dir) {
  const auto r = testing::ErrorOfWithTimeout([&] { LoadDataset(dir, LoadAll()); });
  EXPECT_TRUE(r.finished) << "LoadDataset(" << dir << ") hung";
  return r.message;
}

TEST(HostileDataset, FifosAreRefusedByNameWithoutBlocking) {
  for (const std::string file :
       {"manifest.yaml", "video0/rgb/00001.png", "video0/mask/00002.png",
        "video1/root_poses_init.txt", "video1/root_poses_gt.txt", "video0/flow/fw_1/00000.png",
        "video0/features/00003.npy", "video1/depth/00000.png", "video1/gt_mesh/00004.ply"}) {
    TempDir tmp;
    const std::string dir = WriteValid(tmp);
    const std::string path = dir + "/" + file;
    ASSERT_TRUE(fs::exists(path)) << path;
    fs::remove(path);
    ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
    const std::string error = TimedLoadError(dir);
    EXPECT_NE(error.find(file), std::string::npos) << file << ": " << error;
    EXPECT_NE(error.find("FIFO"), std::string::npos) << file << ": " << error;
  }
}

TEST(HostileDataset, DevZeroAsPoseFileIsRefusedBeforeReading) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string path = dir + "/video0/root_poses_init.txt";
  fs::remove(path);
  fs::create_symlink("/dev/zero", path);
  const std::string error = TimedLoadError(dir);
  EXPECT_NE(error.find("video0/root_poses_init.txt: is a character device"), std::string::npos)
      << error;
}

TEST(HostileDataset, HugeRootPoseTranslationIsRefusedByLine) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string path = dir + "/video0/root_poses_init.txt";
  WriteText(path, "1 0 0 0 0 0 1e308\n" + ReadText(path).substr(ReadText(path).find('\n') + 1));
  const std::string error = TimedLoadError(dir);
  EXPECT_NE(error.find("video0/root_poses_init.txt:1: translation (tx ty tz) beyond"),
            std::string::npos)
      << error;
}

// A 2-frame dataset declaring 32768 x 32768 frames (once 6-7 GB and
// std::bad_alloc): refused from the manifest, before any image is decoded.
TEST(HostileDataset, DeclaredSizesBeyondTheLimitsAreRefusedByKey) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string manifest = dir + "/manifest.yaml";
  const std::string text = ReadText(manifest);
  auto with = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    for (std::size_t at = t.find(from); at != std::string::npos; at = t.find(from, at + 1)) {
      t.replace(at, from.size(), to);
    }
    return t;
  };
  ASSERT_NE(text.find("width: 24"), std::string::npos) << text;
  WriteText(manifest, with("width: 24", "width: 32768"));
  std::string error = TimedLoadError(dir);
  EXPECT_NE(error.find("manifest.yaml"), std::string::npos) << error;
  EXPECT_NE(error.find("image size 32768x20 is beyond the limit"), std::string::npos) << error;
  const std::string wide = with("width: 24", "width: 16000");
  std::string tall = wide;
  for (std::size_t at = tall.find("height: 20"); at != std::string::npos;
       at = tall.find("height: 20", at + 1)) {
    tall.replace(at, 10, "height: 16000");
  }
  WriteText(manifest, tall);
  error = TimedLoadError(dir);
  EXPECT_NE(error.find("16000x16000 is beyond the limit"), std::string::npos) << error;
  // Sizes within the per-frame limit, too many pixels over the dataset.
  std::string many = with("frames: 5", "frames: 100000");
  for (std::size_t at = many.find("width: 24"); at != std::string::npos;
       at = many.find("width: 24", at + 1)) {
    many.replace(at, 9, "width: 2400");
  }
  WriteText(manifest, many);
  error = TimedLoadError(dir);
  EXPECT_NE(error.find("key 'videos': 1 video(s) declare"), std::string::npos) << error;
}

TEST(HostileDataset, DuplicateKeysAndAbsurdDepthUnitAreRefused) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string manifest = dir + "/manifest.yaml";
  const std::string text = ReadText(manifest);
  // A second 'feature_dim' (yaml-cpp would keep the first silently).
  WriteText(manifest, text + "feature_dim: 16\n");
  std::string error = TimedLoadError(dir);
  EXPECT_NE(error.find("manifest.yaml"), std::string::npos) << error;
  EXPECT_NE(error.find("duplicate key 'feature_dim'"), std::string::npos) << error;
  // Inside a video entry.
  const std::size_t frames = text.find("    frames: ");
  ASSERT_NE(frames, std::string::npos) << text;
  std::string video = text;
  video.insert(frames, "    frames: 3\n");
  WriteText(manifest, video);
  error = TimedLoadError(dir);
  EXPECT_NE(error.find("duplicate key 'videos[0].frames'"), std::string::npos) << error;
  // depth_unit 1e308.
  const std::size_t unit = text.find("depth_unit: ");
  ASSERT_NE(unit, std::string::npos) << text;
  std::string depth = text;
  depth.replace(unit, text.find('\n', unit) - unit, "depth_unit: 1e308");
  WriteText(manifest, depth);
  error = TimedLoadError(dir);
  EXPECT_NE(error.find("key 'depth_unit' is 1e+308, expected a number in [1e-9, 1e3]"),
            std::string::npos)
      << error;
}

// The pid of a process that has exited (a killed `prepare --add`).
long DeadPid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return pid;
}

// `prepare --add` killed at each point between its renames: the next
// LoadDataset (check, solve) or add rolls the add back or completes it,
// and the retry works.
TEST(HostileDataset, AddKilledBetweenItsRenamesIsRecovered) {
  Dataset one = MakeSmallDataset();
  one.videos.resize(1);
  one.videos[0].name = "video9";
  for (int point = 0; point < 4; ++point) {
    TempDir tmp;
    const std::string dir = WriteValid(tmp);
    const std::string stage = dir + ".add-" + std::to_string(DeadPid()) + "-7";
    if (point == 3) {  // killed after the manifest's rename: only the staging folder left
      AddVideosToDataset(one, dir, WriteOptions());
      WriteDataset(one, stage, WriteOptions());
    } else {
      WriteDataset(one, stage, WriteOptions());
      if (point >= 1) fs::rename(stage + "/video9", dir + "/video9");  // moved in
      if (point >= 2) {  // the new manifest's temporary file, not yet renamed
        WriteText(dir + "/manifest.yaml.tmp." + std::to_string(DeadPid()) + ".5", "format: x\n");
      }
    }
    const auto r = testing::ErrorOfWithTimeout([&] { LoadDataset(dir, LoadAll()); });
    ASSERT_TRUE(r.finished);
    EXPECT_EQ(r.message, "") << "point " << point;
    EXPECT_FALSE(fs::exists(stage)) << "point " << point;
    for (const auto& e : fs::directory_iterator(dir)) {
      EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos)
          << "point " << point << ": " << e.path();
    }
    const Dataset loaded = LoadDataset(dir, LoadAll());
    EXPECT_EQ(loaded.videos.size(), point == 3 ? 3u : 2u) << "point " << point;
    if (point < 3) {
      EXPECT_FALSE(fs::exists(dir + "/video9")) << "point " << point;
      AddVideosToDataset(one, dir, WriteOptions());  // the retry
      EXPECT_EQ(LoadDataset(dir, LoadAll()).videos.size(), 3u) << "point " << point;
    }
  }
}

// synth / prepare killed while writing a dataset (WriteDataset): the next
// write to the same folder removes the killed run's temporary folder, and a
// kill between the two renames of an --overwrite (old dataset moved aside,
// new one not yet in place) gets the old dataset back.
TEST(HostileDataset, AKilledDatasetWriteIsCleanedUpByTheNextWrite) {
  const Dataset one = MakeSmallDataset();
  TempDir tmp;
  const std::string dir = tmp.path() + "/ds";
  const std::string dead = std::to_string(DeadPid());
  const std::string temp = dir + ".tmp-" + dead + "-12";
  WriteDataset(one, temp, WriteOptions());  // a complete dataset never renamed
  WriteDataset(one, dir, WriteOptions());
  EXPECT_FALSE(fs::exists(temp));
  // Killed between the renames of an overwrite: ds moved aside, not replaced.
  const std::string old = dir + ".old-" + dead + "-3";
  fs::rename(dir, old);
  WriteOptions overwrite;
  overwrite.overwrite = true;
  WriteDataset(one, dir, overwrite);  // restores ds first, then replaces it
  EXPECT_FALSE(fs::exists(old));
  EXPECT_EQ(LoadDataset(dir, LoadAll()).videos.size(), one.videos.size());
  fs::rename(dir, old);
  EXPECT_THROW(WriteDataset(one, dir, WriteOptions()), InputError);  // restored: not empty
  EXPECT_FALSE(fs::exists(old));
  EXPECT_EQ(LoadDataset(dir, LoadAll()).videos.size(), one.videos.size());
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(tmp.path())) {
    left.push_back(e.path().filename().string());
  }
  EXPECT_EQ(left, std::vector<std::string>{"ds"});
}

TEST(HostileDataset, PngHeaderBeyondTheLimitsIsRefusedBeforeDecoding) {
  // Signature and an IHDR of 100000 x 100000 (nothing else: never decoded).
  std::string png("\x89PNG\r\n\x1a\n", 8);
  const unsigned char ihdr[] = {0,    0, 0, 13,   'I',  'H', 'D', 'R', 0, 1, 0x86,
                                0xa0, 0, 1, 0x86, 0xa0, 8,   2,   0,   0, 0};
  png.append(reinterpret_cast<const char*>(ihdr), sizeof(ihdr));
  const std::string error =
      testing::ErrorOfWithTimeout([&] { ParsePngInfo(png, "big.png"); }).message;
  EXPECT_NE(error.find("big.png: PNG of 100000x100000 pixels is beyond the limit"),
            std::string::npos)
      << error;
}

}  // namespace
}  // namespace banmo
