// Shared by the libFuzzer targets (fuzz/CMakeLists.txt, tools/run_fuzz.sh).
// Bad input must end in an InputError; anything else a parser throws
// (std::bad_alloc, std::out_of_range, a filesystem_error) is a finding, as
// are the sanitizers' reports and CHECK failures.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include "banmo/util/error.h"

namespace banmo::fuzz {

// A folder of this fuzzing process, emptied for every input.
inline std::string WorkDir() {
  static const std::string dir = [] {
    const std::string d = std::filesystem::temp_directory_path().string() + "/banmo_fuzz_" +
                          std::to_string(::getpid());
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

// Writes `bytes` to WorkDir()/name and returns the path.
inline std::string WriteInput(const std::string& name, const std::string& bytes) {
  const std::string path = WorkDir() + "/" + name;
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  return path;
}

// Runs `parse`; an InputError is the expected outcome of bad input, any
// other exception aborts (a finding).
inline void Expect(const std::function<void()>& parse) {
  try {
    parse();
  } catch (const InputError&) {
  } catch (const std::exception& e) {
    std::fprintf(stderr, "finding: %s\n", e.what());
    std::abort();
  }
}

inline std::string AsString(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace banmo::fuzz
