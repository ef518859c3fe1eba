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
// (`<name>.tmp.<pid>.<n>`) directly inside `dir`; returns how many.
int RemoveStaleTempFiles(const std::string& dir);

// Outputs of one command written under a staging folder inside `out_dir`
// (`.<name>.staging`) and moved into place by Commit(), file by file with
// rename: a run that fails leaves out_dir without any of its files, and the
// staging folder of a killed run is removed by the next run (with stale
// temporary files of out_dir and its subfolders one level down).
class StagedOutput {
 public:
  StagedOutput(const std::string& out_dir, const std::string& name);
  ~StagedOutput();  // removes the staging folder unless committed
  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;

  // Where to write (the staging folder; same layout as out_dir).
  const std::string& path() const { return staging_; }
  // Moves every file of the staging folder to the same place in out_dir
  // (replacing files of the same name; subfolders are merged) and removes
  // the staging folder. Throws InputError naming the file on failure.
  void Commit();

 private:
  std::string out_dir_;
  std::string staging_;
  bool committed_ = false;
};

}  // namespace banmo
