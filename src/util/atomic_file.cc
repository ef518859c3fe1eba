#include "banmo/util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
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

int RemoveStaleTempFiles(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  int removed = 0;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_regular_file(ec) || !IsTempName(name)) continue;
    if (fs::remove(entry.path(), ec)) ++removed;
  }
  return removed;
}

StagedOutput::StagedOutput(const std::string& out_dir, const std::string& name)
    : out_dir_(out_dir), staging_(out_dir + "/." + name + ".staging") {
  namespace fs = std::filesystem;
  MakeDirectories(out_dir_);
  std::error_code ec;
  fs::remove_all(staging_, ec);  // a killed run's
  RemoveStaleTempFiles(out_dir_);
  for (const auto& entry : fs::directory_iterator(out_dir_, ec)) {
    if (entry.is_directory(ec)) RemoveStaleTempFiles(entry.path().string());
  }
  MakeDirectories(staging_);
}

StagedOutput::~StagedOutput() {
  if (committed_) return;
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
}

void StagedOutput::Commit() {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> files;
  for (auto it = fs::recursive_directory_iterator(staging_, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it->is_regular_file()) files.push_back(it->path());
  }
  if (ec) ThrowInputError(staging_, ": cannot list the staged outputs: ", ec.message());
  for (const fs::path& from : files) {
    const fs::path to = fs::path(out_dir_) / fs::relative(from, staging_);
    MakeDirectories(to.parent_path().string());
    fs::rename(from, to, ec);
    if (ec) ThrowInputError(to.string(), ": cannot move the output into place: ", ec.message());
  }
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
