// Running the built `banmo` executable (BANMO_BINARY) from a test. The test
// target needs `add_dependencies(<test> banmo)` so the executable is current.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

namespace banmo::testing {

struct CommandResult {
  int exit_code = -1;  // -1 if the command could not be started or was killed
  std::string out;     // stdout (and stderr, unless it went to a file)
  std::string err;     // stderr, when it went to a file
};

// Runs `command` through the shell; `out` holds what it printed to stdout.
inline CommandResult RunShell(const std::string& command) {
  CommandResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  std::size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.out.append(buffer, n);
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// Runs `BANMO_BINARY <args>` through the shell. Without `stderr_path`,
// stderr is merged into `out` (in the order it was printed); with it, stderr
// is written to that file and read back into `err`, so `out` holds only what
// the command printed to stdout.
inline CommandResult RunBanmo(const std::string& args, const std::string& stderr_path = "") {
  CommandResult result = RunShell(std::string(BANMO_BINARY) + " " + args +
                                  (stderr_path.empty() ? " 2>&1" : " 2>" + stderr_path));
  if (!stderr_path.empty()) {
    std::ifstream in(stderr_path, std::ios::binary);
    result.err.assign(std::istreambuf_iterator<char>(in), {});
  }
  return result;
}

}  // namespace banmo::testing
