#include "banmo/util/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "banmo/util/error.h"

namespace banmo {
namespace {

const char* KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

[[noreturn]] void ThrowNotRegular(const std::string& path, mode_t mode, const std::string& hint) {
  ThrowInputError(path, ": is ", KindOf(mode), ", expected a regular file", hint);
}

[[noreturn]] void ThrowCannotOpen(const std::string& path, int error, const std::string& hint) {
  ThrowInputError(path, ": cannot open file (", std::strerror(error), ")", hint);
}

// Closes a descriptor on every path out of ReadRegularFile.
class FdCloser {
 public:
  explicit FdCloser(int fd) : fd_(fd) {}
  ~FdCloser() { ::close(fd_); }
  FdCloser(const FdCloser&) = delete;
  FdCloser& operator=(const FdCloser&) = delete;

 private:
  int fd_;
};

}  // namespace

void CheckRegularFile(const std::string& path, const std::string& hint) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) ThrowCannotOpen(path, errno, hint);
  if (!S_ISREG(st.st_mode)) ThrowNotRegular(path, st.st_mode, hint);
}

bool PathExists(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) == 0) return true;
  return errno != ENOENT && errno != ENOTDIR;
}

bool IsSpecialFile(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode);
}

std::string ReadRegularFile(const std::string& path, std::uint64_t max_bytes,
                            const std::string& hint) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) ThrowCannotOpen(path, errno, hint);
  FdCloser closer(fd);
  struct stat st;
  if (::fstat(fd, &st) != 0) ThrowCannotOpen(path, errno, hint);
  if (!S_ISREG(st.st_mode)) ThrowNotRegular(path, st.st_mode, hint);
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_bytes) {
    ThrowInputError(path, ": file of ", size, " bytes is larger than the limit of ", max_bytes,
                    " bytes for this kind of file", hint);
  }
  std::string bytes(static_cast<std::size_t>(size), '\0');
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) ThrowInputError(path, ": read error (", std::strerror(errno), ")", hint);
    if (n == 0) break;  // the file shrank while being read
    done += static_cast<std::size_t>(n);
  }
  if (done != bytes.size()) {
    ThrowInputError(path, ": read error (the file changed size while being read)", hint);
  }
  return bytes;
}

}  // namespace banmo
