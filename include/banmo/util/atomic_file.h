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

// Removes the temporary files WriteFileAtomic* leaves when a run is killed
// (`<name>.tmp.<pid>.<n>`) directly inside `dir`; returns how many. Files of
// a process that is still running are left alone.
int RemoveStaleTempFiles(const std::string& dir);

// Removes the temporary files a killed WriteFileAtomic*(path) left beside
// `path` (`<path>.tmp.<pid>.<n>` of a process that is gone); returns how many.
int RemoveStaleTempFilesOf(const std::string& path);

// True unless the process `pid` is known to be gone (kill(pid, 0) fails with
// ESRCH); false for pid <= 0.
bool ProcessMayBeAlive(long pid);

// The outputs of one command, written into a staging folder and put in place
// by Commit():
// - `out_dir` does not exist yet: the staging folder is its sibling
//   (`<parent>/.<folder>.<name>.staging-<pid>`) and Commit() renames it to
//   `out_dir`: the folder appears whole or not at all.
// - `out_dir` exists (its other files are kept, files of the same names are
//   replaced): the staging folder is `out_dir/.<name>.staging-<pid>`;
//   Commit() first marks it complete (a file `.complete`), then moves its
//   files in one by one and removes it.
// A run that fails leaves nothing (the destructor removes the staging
// folder). The next run for the same out_dir and name recovers what a killed
// run left: a complete staging folder is moved in (the kill came during
// Commit), an incomplete one is removed, and so are stale temporary files of
// out_dir and its subfolders one level down. Staging folders of a process
// that is still running are left alone.
class StagedOutput {
 public:
  StagedOutput(const std::string& out_dir, const std::string& name);
  ~StagedOutput();  // removes the staging folder unless committed
  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;

  // Where to write (the staging folder; same layout as out_dir).
  const std::string& path() const { return staging_; }
  // `staged_path` (a path under path()) as it will be after Commit().
  std::string FinalPath(const std::string& staged_path) const;
  // Puts the staged files in place (see above). Throws InputError naming the
  // file on failure.
  void Commit();
  // What the constructor recovered from killed runs ("" if nothing), e.g.
  // "removed the incomplete staging folder X".
  const std::string& recovery_note() const { return note_; }

 private:
  std::string out_dir_;
  std::string staging_;
  bool fresh_ = false;  // out_dir did not exist: Commit() renames staging_
  bool committed_ = false;
  std::string note_;
};

}  // namespace banmo
