// Errors caused by user input (files, configs, arguments). The command line
// catches InputError, prints its message and exits with status 2. Internal
// invariants use CHECK instead (util/logging.h).
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace banmo {

class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

// A numerical blow-up found by a guard: a non-finite loss, parameter or
// near/far plane. The solver adds the stage and batch and stops; the command
// line reports it like bad input (exit 2), since a configuration (learning
// rate, loss weight) or the data drove the solve there.
class DivergenceError : public InputError {
 public:
  using InputError::InputError;
};

namespace internal {
inline void AppendAll(std::ostringstream&) {}
template <typename First, typename... Rest>
void AppendAll(std::ostringstream& os, First&& first, Rest&&... rest) {
  os << std::forward<First>(first);
  AppendAll(os, std::forward<Rest>(rest)...);
}
}  // namespace internal

// Throws InputError with the arguments streamed into one message, e.g.
//   ThrowInputError(path, ": expected 16 feature channels, found ", c);
template <typename... Args>
[[noreturn]] void ThrowInputError(Args&&... args) {
  std::ostringstream os;
  internal::AppendAll(os, std::forward<Args>(args)...);
  throw InputError(os.str());
}

// Throws DivergenceError with the arguments streamed into one message.
template <typename... Args>
[[noreturn]] void ThrowDivergenceError(Args&&... args) {
  std::ostringstream os;
  internal::AppendAll(os, std::forward<Args>(args)...);
  throw DivergenceError(os.str());
}

}  // namespace banmo
