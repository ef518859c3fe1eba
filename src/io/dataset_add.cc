// AddVideosToDataset: new videos into an existing dataset, written beside it
// first, moved in, manifest replaced last.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <random>
#include <set>

#include "banmo/io/dataset.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "manifest.h"

namespace banmo {
namespace fs = std::filesystem;
namespace {

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

std::string GapsText(const std::vector<int>& gaps) {
  std::string out;
  for (int g : gaps) out += (out.empty() ? "" : ",") + std::to_string(g);
  return "[" + out + "]";
}

void SyncPath(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

// Checks names and gaps of `added` against the existing manifest.
void CheckAddition(const Dataset& added, const std::string& dir, const internal::Manifest& m) {
  if (added.videos.empty()) ThrowInputError("AddVideosToDataset: no videos to add to ", dir);
  std::vector<int> gaps = added.flow_gaps;
  std::sort(gaps.begin(), gaps.end());
  if (gaps != m.flow_gaps) {
    ThrowInputError(dir, ": the dataset's flow gaps are ", GapsText(m.flow_gaps),
                    ", the added video has ", GapsText(gaps),
                    " (every video of a dataset has the same gaps; leave --gaps out to use the "
                    "dataset's)");
  }
  std::vector<std::string> existing;
  for (const internal::ManifestVideo& v : m.videos) existing.push_back(v.name);
  std::set<std::string> names(existing.begin(), existing.end());
  for (const Video& v : added.videos) {
    std::error_code ec;
    if (!names.insert(v.name).second || fs::exists(fs::path(dir) / v.name, ec)) {
      ThrowInputError(dir, ": already has a video named '", v.name,
                      "' (videos: ", JoinNames(existing), "); choose another name (--name)");
    }
  }
}

}  // namespace

DatasetInfo ReadDatasetInfo(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) ThrowInputError(dir, ": not a folder");
  const internal::Manifest m =
      internal::ReadManifest((fs::path(dir) / internal::kManifestName).string());
  DatasetInfo info;
  info.flow_gaps = m.flow_gaps;
  for (const internal::ManifestVideo& v : m.videos) info.video_names.push_back(v.name);
  return info;
}

std::string NextVideoName(const std::vector<std::string>& taken) {
  const std::set<std::string> used(taken.begin(), taken.end());
  for (int i = 0;; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "video_%03d", i);
    if (used.count(name) == 0) return name;
  }
}

void AddVideosToDataset(const Dataset& added, const std::string& dir, const WriteOptions& options) {
  fs::path root = fs::path(dir).lexically_normal();
  if (root.filename().empty()) root = root.parent_path();  // "ds/" -> "ds"
  const std::string manifest_path = (root / internal::kManifestName).string();
  std::error_code ec;
  if (!fs::is_directory(root, ec)) {
    ThrowInputError(dir, ": not a folder (to add a video, the dataset must exist)");
  }
  const internal::Manifest existing = internal::ReadManifest(manifest_path);
  CheckAddition(added, root.string(), existing);

  // 1. The new videos as a dataset of their own, beside the target.
  WriteOptions write = options;
  write.overwrite = false;
  write.flow_encoding = existing.flow_encoding;
  write.depth_encoding = existing.depth_encoding;
  write.depth_unit = existing.depth_unit;
  std::random_device rd;
  const std::string stage =
      root.string() + ".add-" + std::to_string(::getpid()) + "-" + std::to_string(rd() % 1000000);
  std::vector<std::string> moved;  // video folders already moved into root
  try {
    WriteDataset(added, stage, write);
    const internal::Manifest addition =
        internal::ReadManifest((fs::path(stage) / internal::kManifestName).string());
    internal::Manifest merged = existing;
    if (merged.depth_unit <= 0) merged.depth_unit = addition.depth_unit;
    for (const internal::ManifestVideo& v : addition.videos) merged.videos.push_back(v);

    // 2. Move the video folders in (renames within one file system).
    for (const internal::ManifestVideo& v : addition.videos) {
      const fs::path to = root / v.name;
      fs::rename(fs::path(stage) / v.name, to, ec);
      if (ec) {
        ThrowInputError(to.string(),
                        ": could not move the new video into the dataset: ", ec.message());
      }
      moved.push_back(to.string());
    }
    // 3. The manifest last: until this rename the dataset is the old one.
    WriteFileAtomic(manifest_path, internal::EmitManifest(merged));
    SyncPath(root.string());
  } catch (...) {
    for (const std::string& m : moved) fs::remove_all(m, ec);
    fs::remove_all(stage, ec);
    throw;
  }
  fs::remove_all(stage, ec);
  LOG(INFO) << "added " << added.videos.size() << " video(s) to " << root.string();
}

}  // namespace banmo
