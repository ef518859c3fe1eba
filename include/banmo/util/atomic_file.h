// Atomic file output: nothing is lost or half-written. Data goes to a temporary
// file beside the target, is fsync'ed, then renamed over the target.
#pragma once

#include <functional>
#include <string>

namespace banmo {

// Writes `contents` to `path` atomically. Throws InputError naming the path on
// failure (unwritable folder, full disk); the target is then untouched.
void WriteFileAtomic(const std::string& path, const std::string& contents);

// Calls `write(temp_path)` to produce the file under a temporary name in the
// same folder, then fsyncs and renames it to `path`. For writers that need a
// file name (OpenCV, CGAL, tinygltf). If `write` throws or returns false the
// temporary file is removed and InputError is thrown.
void WriteFileAtomicWith(const std::string& path,
                         const std::function<bool(const std::string& temp_path)>& write);

// Creates a directory and its parents; throws InputError on failure.
void MakeDirectories(const std::string& path);

}  // namespace banmo
