#include "banmo/util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

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

void MakeDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) ThrowInputError(path, ": could not create directory: ", ec.message());
}

}  // namespace banmo
