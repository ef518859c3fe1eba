// Running something that could block (a FIFO given as input) with a time
// limit, so that a hang fails the test instead of stalling the suite.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <string>
#include <thread>

#include "banmo/util/error.h"
#include "run_banmo.h"

namespace banmo::testing {

struct TimedError {
  bool finished = false;  // false: still running after the limit (killed)
  std::string message;    // the InputError's message, "" if none was thrown
};

// Calls `fn` in a forked child and returns the message of the InputError it
// throws. The child is killed after `seconds`; then finished is false.
inline TimedError ErrorOfWithTimeout(const std::function<void()>& fn, double seconds = 20) {
  TimedError result;
  int fds[2];
  if (::pipe(fds) != 0) return result;
  const pid_t pid = ::fork();
  if (pid < 0) return result;
  if (pid == 0) {
    ::close(fds[0]);
    std::string message;
    try {
      fn();
    } catch (const InputError& e) {
      message = e.what();
    } catch (...) {
      message = "(an exception that is not an InputError)";
    }
    std::size_t done = 0;
    while (done < message.size()) {
      const ssize_t n = ::write(fds[1], message.data() + done, message.size() - done);
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    ::_exit(0);
  }
  ::close(fds[1]);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      ::close(fds[0]);
      return result;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  char buffer[4096];
  ssize_t n;
  while ((n = ::read(fds[0], buffer, sizeof(buffer))) > 0) result.message.append(buffer, n);
  ::close(fds[0]);
  result.finished = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  return result;
}

// `BANMO_BINARY <args>` (stderr merged into out) under coreutils' timeout:
// exit code 124 (or 137 after the kill) if it did not finish in `seconds`.
inline CommandResult RunBanmoWithTimeout(const std::string& args, int seconds = 60) {
  return RunShell("timeout -k 5 " + std::to_string(seconds) + " " + std::string(BANMO_BINARY) +
                  " " + args + " 2>&1");
}

}  // namespace banmo::testing
