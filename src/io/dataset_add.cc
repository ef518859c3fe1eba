// AddVideosToDataset: new videos into an existing dataset, written beside it
// first, moved in, manifest replaced last.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
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

// The pid in a staging folder's name `<root>.add-<pid>-<n>`, or -1.
long StagePid(const std::string& suffix) {
  const std::size_t dash = suffix.find('-');
  if (dash == std::string::npos || dash == 0) return -1;
  const std::string digits = suffix.substr(0, dash);  // `end` points into it
  char* end = nullptr;
  const long pid = std::strtol(digits.c_str(), &end, 10);
  return end != nullptr && *end == '\0' ? pid : -1;
}

}  // namespace

namespace internal {

std::string RecoverInterruptedAdd(const std::string& dir) {
  fs::path root = fs::path(dir).lexically_normal();
  if (root.filename().empty()) root = root.parent_path();
  const std::string prefix = root.filename().string() + ".add-";
  fs::path parent = root.parent_path();
  if (parent.empty()) parent = ".";
  std::error_code ec;
  std::vector<fs::path> stages;
  for (const auto& entry : fs::directory_iterator(parent, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0 || !entry.is_directory(ec)) continue;
    if (ProcessMayBeAlive(StagePid(name.substr(prefix.size())))) continue;
    stages.push_back(entry.path());
  }
  std::string note;
  const fs::path manifest_path = root / kManifestName;
  for (const fs::path& stage : stages) {
    const fs::path stage_manifest = stage / kManifestName;
    if (fs::exists(stage_manifest, ec) && fs::exists(manifest_path, ec)) {
      std::set<std::string> listed;
      for (const ManifestVideo& v : ReadManifest(manifest_path.string()).videos) {
        listed.insert(v.name);
      }
      Manifest added;
      try {
        added = ReadManifest(stage_manifest.string());
      } catch (const InputError&) {
        // The staging dataset itself was half-written: nothing was moved.
      }
      bool completed = !added.videos.empty();
      for (const ManifestVideo& v : added.videos) completed = completed && listed.count(v.name);
      if (!completed) {
        for (const ManifestVideo& v : added.videos) {
          if (!listed.count(v.name) && fs::exists(root / v.name, ec)) {
            fs::remove_all(root / v.name, ec);
            note += " removed " + (root / v.name).string() + ";";
          }
        }
      }
      note += completed ? " the add had completed;" : " the add was rolled back;";
    }
    fs::remove_all(stage, ec);
    note += " removed " + stage.string() + ";";
  }
  for (const auto& entry : fs::directory_iterator(root, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(std::string(kManifestName) + ".tmp.", 0) != 0) continue;
    const std::string rest = name.substr(std::string(kManifestName).size() + 5);
    if (ProcessMayBeAlive(StagePid(rest.substr(0, rest.find('.')) + "-"))) continue;
    fs::remove(entry.path(), ec);
    note += " removed " + entry.path().string() + ";";
  }
  if (!note.empty()) {
    note = root.string() + ": recovered from an interrupted 'prepare --add':" + note;
    note.pop_back();
    LOG(WARNING) << note;
  }
  return note;
}

}  // namespace internal

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
  internal::RecoverInterruptedAdd(root.string());
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
