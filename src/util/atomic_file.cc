#include "banmo/util/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <vector>

#include "banmo/util/error.h"

namespace banmo {
namespace {

std::string TempPathFor(const std::string& path) {
  std::random_device rd;
  return path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(rd() % 1000000);
}

void FsyncPath(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

// True for TempPathFor's names: "<name>.tmp.<pid>.<n>" (digits only).
bool IsTempName(const std::string& name) {
  const std::size_t at = name.rfind(".tmp.");
  if (at == std::string::npos || at == 0) return false;
  const std::string rest = name.substr(at + 5);
  const std::size_t dot = rest.find('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == rest.size()) return false;
  for (std::size_t i = 0; i < rest.size(); ++i) {
    if (i != dot && !std::isdigit(static_cast<unsigned char>(rest[i]))) return false;
  }
  return true;
}

// The pid in a TempPathFor name (IsTempName true), or -1.
long TempNamePid(const std::string& name) {
  const std::string rest = name.substr(name.rfind(".tmp.") + 5);
  const std::string digits = rest.substr(0, rest.find('.'));
  return digits.size() > 9 ? -1 : std::stol(digits);
}

}  // namespace

void WriteFileAtomicWith(const std::string& path,
                         const std::function<bool(const std::string&)>& write) {
  const std::string temp = TempPathFor(path);
  bool ok = false;
  try {
    ok = write(temp);
  } catch (...) {
    std::remove(temp.c_str());
    throw;
  }
  if (!ok) {
    std::remove(temp.c_str());
    ThrowInputError(path, ": could not write file");
  }
  FsyncPath(temp);
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(temp.c_str());
    ThrowInputError(path, ": could not rename temporary file into place: ", reason);
  }
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  FsyncPath(parent.empty() ? "." : parent.string());
}

void WriteFileAtomic(const std::string& path, const std::string& contents) {
  WriteFileAtomicWith(path, [&contents](const std::string& temp) {
    std::FILE* f = std::fopen(temp.c_str(), "wb");
    if (f == nullptr) return false;
    const bool written = std::fwrite(contents.data(), 1, contents.size(), f) == contents.size();
    return (std::fclose(f) == 0) && written;
  });
}

bool ProcessMayBeAlive(long pid) {
  if (pid <= 0) return false;
  return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH;
}

int RemoveStaleTempFiles(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  int removed = 0;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_regular_file(ec) || !IsTempName(name)) continue;
    if (ProcessMayBeAlive(TempNamePid(name))) continue;
    if (fs::remove(entry.path(), ec)) ++removed;
  }
  return removed;
}

int RemoveStaleTempFilesOf(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const std::string prefix = target.filename().string() + ".tmp.";
  const fs::path parent = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  int removed = 0;
  for (const auto& entry : fs::directory_iterator(parent, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0 || !entry.is_regular_file(ec) || !IsTempName(name)) continue;
    if (ProcessMayBeAlive(TempNamePid(name))) continue;
    if (fs::remove(entry.path(), ec)) ++removed;
  }
  return removed;
}

namespace {

constexpr const char* kCompleteMarker = ".complete";

// Moves every regular file under `staging` (but its marker) to the same
// place under `out_dir`, replacing files of the same name.
void MoveStagedFiles(const std::filesystem::path& staging, const std::filesystem::path& out_dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> files;
  for (auto it = fs::recursive_directory_iterator(staging, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it->is_regular_file() && it->path() != staging / kCompleteMarker) {
      files.push_back(it->path());
    }
  }
  if (ec) ThrowInputError(staging.string(), ": cannot list the staged outputs: ", ec.message());
  for (const fs::path& from : files) {
    const fs::path to = out_dir / fs::relative(from, staging);
    MakeDirectories(to.parent_path().string());
    fs::rename(from, to, ec);
    if (ec) ThrowInputError(to.string(), ": cannot move the output into place: ", ec.message());
  }
  FsyncPath(out_dir.string());
}

// The staging folders of killed runs: entries of `dir` named `prefix` or
// `prefix-<pid>` with the process gone.
std::vector<std::filesystem::path> DeadStagingFolders(const std::filesystem::path& dir,
                                                      const std::string& prefix) {
  namespace fs = std::filesystem;
  std::vector<fs::path> found;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0 || !entry.is_directory(ec)) continue;
    const std::string rest = name.substr(prefix.size());
    long pid = -1;  // `prefix` alone: the name before the pid was added
    if (!rest.empty()) {
      if (rest[0] != '-' || rest.size() == 1) continue;
      char* end = nullptr;
      const std::string digits = rest.substr(1);
      pid = std::strtol(digits.c_str(), &end, 10);
      if (end == nullptr || *end != '\0') continue;
    }
    if (!ProcessMayBeAlive(pid)) found.push_back(entry.path());
  }
  return found;
}

}  // namespace

StagedOutput::StagedOutput(const std::string& out_dir, const std::string& name) {
  namespace fs = std::filesystem;
  fs::path out = fs::path(out_dir).lexically_normal();
  if (out.filename().empty() && out.has_parent_path()) out = out.parent_path();
  out_dir_ = out.string();
  const std::string base = out.filename().string();
  const bool can_be_sibling = !base.empty() && base != "." && base != "..";
  fs::path parent = out.parent_path();
  if (parent.empty()) parent = ".";
  const std::string pid = std::to_string(::getpid());

  // Killed runs: a complete staging folder is moved in, others removed.
  std::error_code ec;
  std::vector<fs::path> dead;
  if (can_be_sibling) dead = DeadStagingFolders(parent, "." + base + "." + name + ".staging");
  if (fs::is_directory(out, ec)) {
    for (const fs::path& p : DeadStagingFolders(out, "." + name + ".staging")) dead.push_back(p);
  }
  for (const fs::path& stage : dead) {
    if (fs::exists(stage / kCompleteMarker, ec)) {
      MoveStagedFiles(stage, out);
      note_ += "moved in the complete outputs of a killed run from " + stage.string() + "; ";
    } else {
      note_ += "removed the incomplete staging folder " + stage.string() + "; ";
    }
    fs::remove_all(stage, ec);
  }

  fresh_ = can_be_sibling && !fs::exists(fs::symlink_status(out, ec));
  if (fresh_) {
    MakeDirectories(parent.string());
    staging_ = (parent / ("." + base + "." + name + ".staging-" + pid)).string();
  } else {
    MakeDirectories(out_dir_);
    int removed = RemoveStaleTempFiles(out_dir_);
    for (const auto& entry : fs::directory_iterator(out_dir_, ec)) {
      if (entry.is_directory(ec)) removed += RemoveStaleTempFiles(entry.path().string());
    }
    if (removed > 0) {
      note_ += "removed " + std::to_string(removed) + " temporary file(s) of killed runs; ";
    }
    staging_ = (out / ("." + name + ".staging-" + pid)).string();
  }
  fs::remove_all(staging_, ec);  // an earlier process with the same pid
  MakeDirectories(staging_);
  if (!note_.empty()) note_.resize(note_.size() - 2);
}

StagedOutput::~StagedOutput() {
  if (committed_) return;
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
}

std::string StagedOutput::FinalPath(const std::string& staged_path) const {
  namespace fs = std::filesystem;
  const fs::path relative = fs::path(staged_path).lexically_relative(staging_);
  if (relative.empty() || *relative.begin() == "..") return staged_path;
  return (fs::path(out_dir_) / relative).lexically_normal().string();
}

void StagedOutput::Commit() {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fresh_) {
    // One rename: out_dir appears whole. An empty out_dir made meanwhile is
    // replaced; anything else there makes it a merge.
    fs::rename(staging_, out_dir_, ec);
    if (!ec) {
      const fs::path parent = fs::path(out_dir_).parent_path();
      FsyncPath(parent.empty() ? "." : parent.string());
      committed_ = true;
      return;
    }
  }
  // From here a kill leaves a complete staging folder, which the next run
  // moves in.
  WriteFileAtomic((fs::path(staging_) / kCompleteMarker).string(), "");
  FsyncPath(staging_);
  MoveStagedFiles(staging_, out_dir_);
  fs::remove_all(staging_, ec);
  FsyncPath(out_dir_);
  committed_ = true;
}

void MakeDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) ThrowInputError(path, ": could not create directory: ", ec.message());
}

}  // namespace banmo
