// Reading user-given files safely. Only regular files are read: a FIFO, a
// device, a socket or a directory is refused before any byte is read (so a
// FIFO cannot block and /dev/zero cannot fill memory), and a file larger than
// the caller's limit is refused before it is read. Errors are InputError
// naming the path (exit 2). The limits are listed in docs/robustness.md.
#pragma once

#include <cstdint>
#include <string>

namespace banmo {

// Default limit of ReadRegularFile: 4 GiB.
inline constexpr std::uint64_t kMaxInputFileBytes = std::uint64_t{4} << 30;
// Limit for text and YAML files (manifests, configs, pose files, checkpoint
// and model YAML): 64 MiB, far above any file banmo writes.
inline constexpr std::uint64_t kMaxTextFileBytes = std::uint64_t{64} << 20;

// True unless `path` certainly does not exist (ENOENT, ENOTDIR). Never
// throws: a symbolic link loop or an unreadable folder counts as existing, so
// that the read which follows names the problem (std::filesystem::exists
// throws there, which ended as an internal error).
bool PathExists(const std::string& path);

// Throws InputError naming `path` unless it names an existing regular file
// (symbolic links are followed; a symbolic link loop is refused by name).
// `hint` is appended to the message (e.g. what to do instead).
void CheckRegularFile(const std::string& path, const std::string& hint = "");

// True if `path` exists (following links) and is not a regular file: a
// directory, FIFO, device or socket. Never blocks.
bool IsSpecialFile(const std::string& path);

// The whole contents of the regular file `path`. The file is opened without
// blocking and checked on the open descriptor (no race with a swap), then
// read. Throws InputError naming the path if it is missing, not a regular
// file, larger than `max_bytes` or unreadable; `hint` is appended.
std::string ReadRegularFile(const std::string& path, std::uint64_t max_bytes = kMaxInputFileBytes,
                            const std::string& hint = "");

}  // namespace banmo
